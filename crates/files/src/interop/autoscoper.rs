//! Autoscoper's trial configuration (`.cfg`, version 1.2): key-value lines, `#` comments,
//! relative paths without a leading `/`, one `mayaCam_csv` and one `CameraRootDir` per camera in
//! the same order.

/// The `.cfg` of one exposure of a run folder written by `rsasim export --to autoscoper`:
/// cameras `calibration/<detector>_MayaCam.txt`, images `images/<exposure>-<detector>/`, and a
/// `MeshFile` per model of the exposure (`models/<phantom>.stl`).
pub fn trial_cfg(detectors: &[&str], exposure: &str, models: &[&str]) -> String {
    let mut s = format!(
        "# Autoscoper trial written by {}: exposure `{exposure}` of one rsasim run.\n\
         # Cameras hold the calibration named in ../README.md; images are the run's, rows flipped.\n\
         # Autoscoper tracks with a CT volume of each model (VolumeFile, VolumeFlip, VoxelSize);\n\
         # rsasim models are meshes, so add those keys for the model you track.\n\
         Version 1.2\n\n",
        crate::output::program()
    );
    for d in detectors {
        s += &format!("mayaCam_csv calibration/{d}_MayaCam.txt\n");
    }
    s.push('\n');
    for d in detectors {
        s += &format!("CameraRootDir images/{exposure}-{d}/\n");
    }
    if !models.is_empty() {
        s.push('\n');
        for m in models {
            s += &format!("MeshFile models/{m}.stl\n");
        }
    }
    s += "\nRenderResolution 512 512\n\nOptimizationOffsets 0.1 0.1 0.1 0.1 0.1 0.1\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cameras_and_folders_pair_in_order() {
        let t = trial_cfg(&["det1", "det2"], "model", &["femur"]);
        let keys: Vec<&str> = t
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty())
            .collect();
        assert_eq!(
            keys,
            [
                "Version 1.2",
                "mayaCam_csv calibration/det1_MayaCam.txt",
                "mayaCam_csv calibration/det2_MayaCam.txt",
                "CameraRootDir images/model-det1/",
                "CameraRootDir images/model-det2/",
                "MeshFile models/femur.stl",
                "RenderResolution 512 512",
                "OptimizationOffsets 0.1 0.1 0.1 0.1 0.1 0.1",
            ]
        );
    }
}
