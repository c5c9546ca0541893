//! The four reference beads of a calibration box, chosen by rule for XMALab's cube calibration.
//!
//! XMALab asks the user to click four reference beads of the calibration object in every camera's
//! calibration image, names them in the references file (`CalibrationObject::loadCoords`), and
//! places the rest of the object from them. Four beads serve only if the user can find each one
//! unmistakably in every view and if they pin the object down in 3-D. A bead qualifies when, in
//! every calibration view (every image of an exposure that holds the box):
//!
//! - its projected centre lies on the image, at least [`MIN_SEPARATION_DIAMETERS`] of its own
//!   image diameters from the border;
//! - its projected centre lies at least [`MIN_SEPARATION_DIAMETERS`] bead-image diameters (the
//!   larger of the two beads') from the projected centre of every other bead of the exposure;
//! - it is not hidden by an implant (truth's `occluded`);
//! - the ray from the source to it meets its plate at least [`MIN_PLATE_ANGLE_DEG`] from
//!   edge-on (a plate seen edge-on shows its beads in rows a few pixels apart).
//!
//! Among the qualifying beads, the four spanning the largest tetrahedron are chosen: every four
//! of the beads extreme along the 26 directions of a cube's faces, edges and corners (they stand
//! for the convex hull, whose vertices the largest tetrahedron takes), then single swaps against
//! every qualifying bead while the volume grows. The tetrahedron must hold at least
//! [`MIN_VOLUME_FRACTION`] of the volume of the box beads' bounding box (axis-aligned in the
//! box frame): four beads on one plate, or on two parallel lines, do not fix a 3-D pose.

use glam::DVec3;

use super::camera::PinholeCamera;

/// Least distance between a reference bead's image and any other bead's image, and between its
/// image and the image border, in bead-image diameters.
pub const MIN_SEPARATION_DIAMETERS: f64 = 3.0;

/// Least angle between the ray to a reference bead and the plane of its plate, degrees.
pub const MIN_PLATE_ANGLE_DEG: f64 = 10.0;

/// Least volume of the reference tetrahedron, as a fraction of the box beads' bounding box.
pub const MIN_VOLUME_FRACTION: f64 = 0.05;

/// The most box beads the choice examines. Each bead's crowding check looks at every other
/// bead's image, so the work grows with the square of their number, and a scenario may hold up
/// to a million beads per plate (a received truth any number). A box with more beads gets no
/// calibration object: XMALab needs four reference beads, and the cameras hold the calibration.
pub const MAX_BOX_BEADS: usize = 10_000;

/// A bead of the calibration box, box frame.
#[derive(Debug, Clone)]
pub struct BoxBead {
    /// Centre, mm.
    pub position_mm: DVec3,
    /// Diameter, mm.
    pub diameter_mm: f64,
    /// Unit normal of its plate, box frame (`None`: not on a plate).
    pub plate_normal: Option<DVec3>,
}

/// One calibration view: a camera and every bead of its exposure.
#[derive(Debug, Clone)]
pub struct View {
    /// The source (focus), mm.
    pub source_mm: DVec3,
    /// The camera of the exported (flipped) image.
    pub camera: PinholeCamera,
    /// Every bead of the exposure, the box's included: centre (mm) and diameter (mm).
    pub beads: Vec<(DVec3, f64)>,
    /// Per box bead (same order as the box beads): hidden by an implant in this view.
    pub hidden: Vec<bool>,
}

/// Why beads failed to qualify, counted over the box.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Rejections {
    /// Off the image (or too near its border) in some view.
    pub off_image: usize,
    /// Too near another bead's image in some view.
    pub crowded: usize,
    /// On a plate seen within [`MIN_PLATE_ANGLE_DEG`] of edge-on in some view.
    pub edge_on: usize,
    /// Hidden by an implant in some view.
    pub hidden: usize,
}

/// The outcome of a choice that found no four.
#[derive(Debug, Clone, PartialEq)]
pub struct NoFour {
    /// Beads that qualified.
    pub qualified: usize,
    /// Why the others did not.
    pub rejections: Rejections,
    /// The largest tetrahedron among the qualified beads as a fraction of the bounding box
    /// (0 with fewer than four).
    pub volume_fraction: f64,
    /// The number of box beads when it is beyond [`MAX_BOX_BEADS`] (none was examined).
    pub too_many: Option<usize>,
}

impl std::fmt::Display for NoFour {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(n) = self.too_many {
            return write!(
                f,
                "no reference beads are chosen for XMALab's cube calibration: the box has {n} beads, more than the {MAX_BOX_BEADS} the choice examines"
            );
        }
        let r = &self.rejections;
        write!(
            f,
            "no four reference beads qualify for XMALab's cube calibration: {} bead(s) qualify in every calibration view (rejected: {} off the image or within {MIN_SEPARATION_DIAMETERS} diameters of its border, {} within {MIN_SEPARATION_DIAMETERS} bead diameters of another bead's image, {} on a plate seen within {MIN_PLATE_ANGLE_DEG}° of edge-on, {} hidden by an implant)",
            self.qualified, r.off_image, r.crowded, r.edge_on, r.hidden
        )?;
        if self.qualified >= 4 {
            write!(
                f,
                "; the largest tetrahedron they span holds {:.4} of the beads' bounding box, less than {MIN_VOLUME_FRACTION}",
                self.volume_fraction
            )?;
        }
        Ok(())
    }
}

/// Why a bead fails in one view, or `None` when it serves there.
fn fails_in(bead: &BoxBead, index: usize, view: &View) -> Option<fn(&mut Rejections)> {
    let cam = &view.camera;
    let Some(centre) = cam.project(bead.position_mm) else {
        return Some(|r| r.off_image += 1);
    };
    let diameter_px = |p: DVec3, d_mm: f64| -> f64 {
        let depth: f64 = (0..3).map(|i| cam.r[2][i] * p[i]).sum::<f64>() + cam.t[2];
        cam.k[0][0].max(cam.k[1][1]) * d_mm / depth
    };
    let own = diameter_px(bead.position_mm, bead.diameter_mm);
    let margin = MIN_SEPARATION_DIAMETERS * own;
    let [w, h] = cam.size.map(f64::from);
    // OpenCV pixel centres: the image spans [−0.5, W − 0.5] × [−0.5, H − 0.5].
    if !(centre[0] + 0.5 >= margin
        && centre[0] + 0.5 <= w - margin
        && centre[1] + 0.5 >= margin
        && centre[1] + 0.5 <= h - margin)
    {
        return Some(|r| r.off_image += 1);
    }
    if view.hidden.get(index).copied().unwrap_or(false) {
        return Some(|r| r.hidden += 1);
    }
    if let Some(n) = bead.plate_normal {
        let ray = (bead.position_mm - view.source_mm).normalize();
        let angle_deg = n.dot(ray).abs().clamp(0.0, 1.0).asin().to_degrees();
        if angle_deg < MIN_PLATE_ANGLE_DEG {
            return Some(|r| r.edge_on += 1);
        }
    }
    for &(p, d_mm) in &view.beads {
        if p == bead.position_mm {
            continue;
        }
        let Some(other) = cam.project(p) else {
            continue;
        };
        let apart = ((other[0] - centre[0]).powi(2) + (other[1] - centre[1]).powi(2)).sqrt();
        if apart < MIN_SEPARATION_DIAMETERS * own.max(diameter_px(p, d_mm)) {
            return Some(|r| r.crowded += 1);
        }
    }
    None
}

/// Six times the volume of the tetrahedron (a, b, c, d).
fn volume6(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    (b - a).dot((c - a).cross(d - a)).abs()
}

/// The four beads of `candidates` (indices into `beads`, ascending) spanning the largest
/// tetrahedron found by the deterministic search of the module docs, and six times its volume.
fn largest_tetrahedron(beads: &[BoxBead], candidates: &[usize]) -> Option<([usize; 4], f64)> {
    if candidates.len() < 4 {
        return None;
    }
    let p = |i: usize| beads[i].position_mm;
    // The vertices of the largest tetrahedron are vertices of the convex hull; the beads
    // extreme along the 26 directions of a cube's faces, edges and corners stand for them.
    let mut extremes: Vec<usize> = Vec::new();
    for dx in -1..=1 {
        for dy in -1..=1 {
            for dz in -1..=1 {
                if (dx, dy, dz) == (0, 0, 0) {
                    continue;
                }
                let dir = DVec3::new(f64::from(dx), f64::from(dy), f64::from(dz));
                let best =
                    candidates
                        .iter()
                        .copied()
                        .fold(None, |best: Option<(usize, f64)>, i| {
                            let s = p(i).dot(dir);
                            match best {
                                Some((_, b)) if b >= s => best,
                                _ => Some((i, s)),
                            }
                        });
                if let Some((i, _)) = best
                    && !extremes.contains(&i)
                {
                    extremes.push(i);
                }
            }
        }
    }
    let vol = |f: &[usize; 4]| volume6(p(f[0]), p(f[1]), p(f[2]), p(f[3]));
    let mut four = [candidates[0], candidates[1], candidates[2], candidates[3]];
    let mut best = vol(&four);
    let m = extremes.len();
    for a in 0..m {
        for b in a + 1..m {
            for c in b + 1..m {
                for d in c + 1..m {
                    let trial = [extremes[a], extremes[b], extremes[c], extremes[d]];
                    let v = vol(&trial);
                    if v > best {
                        four = trial;
                        best = v;
                    }
                }
            }
        }
    }
    // Single swaps against every candidate while the volume grows (each strictly, so this ends).
    loop {
        let mut improved = false;
        for k in 0..4 {
            for &i in candidates {
                if four.contains(&i) {
                    continue;
                }
                let mut trial = four;
                trial[k] = i;
                let v = vol(&trial);
                if v > best * (1.0 + 1e-12) {
                    four = trial;
                    best = v;
                    improved = true;
                }
            }
        }
        if !improved {
            break;
        }
    }
    four.sort_unstable();
    Some((four, best))
}

/// Volume of the axis-aligned bounding box of the beads, mm³.
fn bounding_volume(beads: &[BoxBead]) -> f64 {
    let (lo, hi) = beads.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), b| (lo.min(b.position_mm), hi.max(b.position_mm)),
    );
    let e = (hi - lo).max(DVec3::ZERO);
    e.x * e.y * e.z
}

/// The four reference beads (indices into `beads`, ascending) by the rule of the module docs.
pub fn choose(beads: &[BoxBead], views: &[View]) -> Result<[usize; 4], NoFour> {
    if beads.len() > MAX_BOX_BEADS {
        return Err(NoFour {
            qualified: 0,
            rejections: Rejections::default(),
            volume_fraction: 0.0,
            too_many: Some(beads.len()),
        });
    }
    let mut rejections = Rejections::default();
    let mut qualified = Vec::new();
    for (i, bead) in beads.iter().enumerate() {
        match views.iter().find_map(|v| fails_in(bead, i, v)) {
            Some(count) => count(&mut rejections),
            None => qualified.push(i),
        }
    }
    let box_volume = bounding_volume(beads);
    let found = largest_tetrahedron(beads, &qualified);
    let fraction = match (&found, box_volume > 0.0) {
        (Some((_, v6)), true) => v6 / 6.0 / box_volume,
        _ => 0.0,
    };
    match found {
        Some((four, _)) if fraction >= MIN_VOLUME_FRACTION => Ok(four),
        _ => Err(NoFour {
            qualified: qualified.len(),
            rejections,
            volume_fraction: fraction,
            too_many: None,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expand::DetectorState;
    use glam::DMat3;

    fn bead(x: f64, y: f64, z: f64, normal: DVec3) -> BoxBead {
        BoxBead {
            position_mm: DVec3::new(x, y, z),
            diameter_mm: 1.0,
            plate_normal: Some(normal),
        }
    }

    /// A camera looking down −z from (0, 0, 1000) onto a 1000 × 1000 detector of 0.4 mm pixels
    /// in the plane z = −100: magnification 1.1 at z = 0.
    fn view(beads: &[BoxBead]) -> View {
        let det = DetectorState {
            id: "d".into(),
            source: "s".into(),
            position_mm: DVec3::new(0.0, 0.0, -100.0),
            rotation: DMat3::IDENTITY,
            pixels: [1000, 1000],
            pixel_pitch_mm: [0.4, 0.4],
            bpp: 12,
        };
        let source = DVec3::new(0.0, 0.0, 1000.0);
        View {
            source_mm: source,
            camera: PinholeCamera::of_beamline(source, &det).unwrap(),
            beads: beads
                .iter()
                .map(|b| (b.position_mm, b.diameter_mm))
                .collect(),
            hidden: vec![false; beads.len()],
        }
    }

    #[test]
    fn a_box_of_more_beads_than_the_cap_is_refused_at_once_and_says_why() {
        // A received truth with its box beads repeated many times (the fuzzer's seed 830 for
        // export-xmalab: 100,049 markers took 17 s in the crowding check): refused before any
        // bead is examined.
        let one = bead(40.0, 40.0, 0.0, DVec3::Z);
        let beads = vec![one.clone(); MAX_BOX_BEADS + 1];
        let v = view(&beads[..1]);
        let e = choose(&beads, &[v]).unwrap_err();
        assert_eq!(e.too_many, Some(MAX_BOX_BEADS + 1));
        assert!(
            e.to_string()
                .contains("the box has 10001 beads, more than the 10000"),
            "{e}"
        );
        // Below the cap the beads are examined (five copies of one bead span no tetrahedron).
        let few = vec![one; 5];
        let e = choose(&few, &[view(&few)]).unwrap_err();
        assert!(e.too_many.is_none() && e.qualified == 5, "{e:?}");
    }

    #[test]
    fn four_on_one_plate_never_qualify_and_the_error_says_why() {
        // One plate: every tetrahedron is flat.
        let beads: Vec<BoxBead> = (0..5)
            .flat_map(|i| (0..5).map(move |j| (i, j)))
            .map(|(i, j)| bead(f64::from(i) * 20.0, f64::from(j) * 20.0, 0.0, DVec3::Z))
            .collect();
        let v = view(&beads);
        let e = choose(&beads, &[v]).unwrap_err();
        assert_eq!(e.qualified, 25);
        assert_eq!(e.volume_fraction, 0.0);
        assert!(e.to_string().contains("25 bead(s) qualify"), "{e}");
    }

    #[test]
    fn two_plates_give_the_largest_tetrahedron_found_by_brute_force() {
        // Plates z = 0 and z = 100, beads at 40, 60, …, 120 mm in x and y: off the axis, so the
        // near plate's beads do not cover the far plate's. The largest tetrahedron takes crossed
        // diagonals of the two plates: 80·80·100/3 mm³, a third of the bounding box.
        let mut beads = Vec::new();
        for z in [0.0, 100.0] {
            for i in 0..5 {
                for j in 0..5 {
                    let (x, y) = (40.0 + f64::from(i) * 20.0, 40.0 + f64::from(j) * 20.0);
                    beads.push(bead(x, y, z, DVec3::Z));
                }
            }
        }
        let v = view(&beads);
        let four = choose(&beads, std::slice::from_ref(&v)).unwrap();
        let p = |i: usize| beads[i].position_mm;
        let v6 = volume6(p(four[0]), p(four[1]), p(four[2]), p(four[3]));
        assert!(
            (v6 / 6.0 - 80.0 * 80.0 * 100.0 / 3.0).abs() < 1e-6,
            "{four:?}"
        );
        // Brute force over every four of the qualifying beads.
        let q: Vec<usize> = (0..beads.len())
            .filter(|&i| fails_in(&beads[i], i, &v).is_none())
            .collect();
        assert_eq!(q.len(), 50);
        let mut best: f64 = 0.0;
        for a in 0..q.len() {
            for b in a + 1..q.len() {
                for c in b + 1..q.len() {
                    for d in c + 1..q.len() {
                        best = best.max(volume6(p(q[a]), p(q[b]), p(q[c]), p(q[d])));
                    }
                }
            }
        }
        assert!((v6 - best).abs() < 1e-6 * best, "{v6} {best}");
    }

    #[test]
    fn crowded_edge_on_hidden_and_off_image_beads_are_rejected() {
        let mut beads = vec![
            bead(0.0, 0.0, 0.0, DVec3::Z),
            bead(1.0, 0.0, 0.0, DVec3::Z), // 2.75 px from the first: crowded (both)
            bead(60.0, 0.0, 0.0, DVec3::X), // plate seen edge-on (ray 3.4° from its plane)
            bead(0.0, 60.0, 0.0, DVec3::Z),
            bead(500.0, 0.0, 0.0, DVec3::Z), // off the 400 mm field
        ];
        beads.push(bead(0.0, -60.0, 0.0, DVec3::Z));
        let mut v = view(&beads);
        v.hidden[5] = true;
        let e = choose(&beads, &[v]).unwrap_err();
        assert_eq!(
            e.rejections,
            Rejections {
                off_image: 1,
                crowded: 2,
                edge_on: 1,
                hidden: 1
            }
        );
        assert_eq!(e.qualified, 1);
    }
}
