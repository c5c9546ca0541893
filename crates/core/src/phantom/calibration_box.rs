//! Bead layout of a calibration box: plates of rectangular bead grids.

use glam::DVec3;

use super::Marker;
use crate::geometry::Pose;
use crate::scenario::{CalibrationBox, Plate};

/// Every bead of the box, in the box's local frame, plate by plate, row by row, column by column.
///
/// The bead at grid column `i`, row `j` of a plate sits at
/// `plate_pose · ((i − (nx−1)/2)·sx, (j − (ny−1)/2)·sy, 0)`, so the grid is centred on
/// `center_mm`; its id is `<plate>-<jj>-<ii>` (row, then column, two digits each).
pub fn box_markers(b: &CalibrationBox) -> Vec<Marker> {
    b.plates.iter().flat_map(plate_markers).collect()
}

fn plate_markers(p: &Plate) -> Vec<Marker> {
    let pose = Pose::from_position_euler_deg(p.center_mm, p.rotation_deg);
    let [nx, ny] = p.grid;
    let mut out = Vec::with_capacity((nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            if p.omit.contains(&[i, j]) {
                continue;
            }
            let local = DVec3::new(
                (i as f64 - (nx - 1) as f64 / 2.0) * p.spacing_mm[0],
                (j as f64 - (ny - 1) as f64 / 2.0) * p.spacing_mm[1],
                0.0,
            );
            out.push(Marker {
                id: format!("{}-{j:02}-{i:02}", p.id),
                position_mm: pose.to_world(local),
                diameter_mm: p.bead_diameter_mm,
                plate: Some(p.id.clone()),
                role: Some(p.role),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::PlateRole;

    #[test]
    fn grid_is_centred_rotated_and_omits_positions() {
        let plate = Plate {
            id: "F".into(),
            role: PlateRole::Fiducial,
            center_mm: [0.0, 0.0, -100.0],
            rotation_deg: [0.0, 90.0, 0.0],
            size_mm: [100.0, 100.0],
            grid: [3, 2],
            spacing_mm: [10.0, 20.0],
            bead_diameter_mm: 1.0,
            omit: vec![[2, 1]],
            thickness_mm: None,
            material: None,
        };
        let m = box_markers(&CalibrationBox {
            plates: vec![plate],
        });
        assert_eq!(m.len(), 5);
        assert_eq!(m[0].id, "F-00-00");
        // Column 0, row 0: local (−10, −10, 0); Ry(90°) maps local x to −z.
        assert!((m[0].position_mm - DVec3::new(0.0, -10.0, -90.0)).length() < 1e-12);
        assert!(m.iter().all(|b| b.id != "F-01-02"));
    }
}
