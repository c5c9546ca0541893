//! Autoscoper's trial configuration (`.cfg`, version 1.2): key-value lines (the key ends at the
//! first space), `#` comments, relative paths without a leading `/`, one `mayaCam_csv` and one
//! `CameraRootDir` per camera in the same order, at least one `VolumeFile` with as many
//! `VoxelSize` and 0 or as many `MeshFile` (`Trial::parse`, `Trial::validate` in Autoscoper's
//! `libautoscoper/src/Trial.cpp`).

/// A volume of a trial: its phantom (files `../volumes/<phantom>.tif` and `.stl`, shared by the
/// runs of an export), its voxel size, and the offset of its frame in the phantom's frame.
#[derive(Debug, Clone)]
pub struct TrialVolume<'a> {
    /// Phantom id.
    pub phantom: &'a str,
    /// Voxel size, mm (isotropic).
    pub voxel_mm: f64,
    /// `a` of [`super::volume`], mm.
    pub offset_mm: [f64; 3],
}

/// The `.cfg` of one exposure of a run folder written by `rsasim export --to autoscoper`:
/// cameras `calibration/<detector>_MayaCam.txt`, images `images/<exposure>-<detector>/`, and per
/// model of the exposure a `VolumeFile` (`VolumeFlip 0 1 1`, isotropic `VoxelSize`) with its
/// `MeshFile` in the volume frame, in the same order (Autoscoper pairs them by order,
/// `Trial::parse`). Paths are relative to the cfg (Version ≥ 1.1).
pub fn trial_cfg(detectors: &[&str], exposure: &str, volumes: &[TrialVolume]) -> String {
    let mut s = format!(
        "# Autoscoper trial written by {}: exposure `{exposure}` of one rsasim run.\n\
         # Cameras hold the calibration named in ../README.md; images are the run's, rows flipped.\n\
         # Volumes: the models voxelized, value = round(6553.5 · mu / (1/mm)), 0 outside.\n\
         # Volume frame = phantom frame minus the offset below (mm); truth/ holds the true poses.\n",
        crate::output::program()
    );
    for v in volumes {
        s += &format!(
            "#   {}: offset {} {} {}\n",
            v.phantom, v.offset_mm[0], v.offset_mm[1], v.offset_mm[2]
        );
    }
    s += "Version 1.2\n\n";
    for d in detectors {
        s += &format!("mayaCam_csv calibration/{d}_MayaCam.txt\n");
    }
    s.push('\n');
    for d in detectors {
        s += &format!("CameraRootDir images/{exposure}-{d}/\n");
    }
    if !volumes.is_empty() {
        s.push('\n');
        for v in volumes {
            s += &format!("VolumeFile ../volumes/{}.tif\n", v.phantom);
            s += "VolumeFlip 0 1 1\n";
            s += &format!("VoxelSize {0} {0} {0}\n", v.voxel_mm);
        }
        s.push('\n');
        for v in volumes {
            s += &format!("MeshFile ../volumes/{}.stl\n", v.phantom);
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
        let t = trial_cfg(
            &["det1", "det2"],
            "model",
            &[TrialVolume {
                phantom: "femur",
                voxel_mm: 0.5,
                offset_mm: [-1.0, 2.0, 3.5],
            }],
        );
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
                "VolumeFile ../volumes/femur.tif",
                "VolumeFlip 0 1 1",
                "VoxelSize 0.5 0.5 0.5",
                "MeshFile ../volumes/femur.stl",
                "RenderResolution 512 512",
                "OptimizationOffsets 0.1 0.1 0.1 0.1 0.1 0.1",
            ]
        );
    }
}
