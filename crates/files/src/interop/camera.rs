//! A beamline as the pinhole camera XMALab and Autoscoper use (OpenCV model), its MayaCam 2.0
//! text and its DLT-11 coefficients.
//!
//! # Why the exported images are flipped
//!
//! rsasim's detector frame has r × c = s with s pointing towards the source, so an image as rsasim
//! stores it (u along r, v along c) is the mirror image of what a pinhole camera at the source
//! would see: no rotation with determinant +1 and positive focal lengths describes it. The
//! exported images are therefore written bottom row first (row j of the export is row H − 1 − j of
//! rsasim's image). The camera of the flipped image has the axes x = r, y = −c, z = −s (world →
//! camera rows of R), focal lengths f_x = d / pitch_x and f_y = d / pitch_y with d the
//! source-to-detector-plane distance, and no skew.
//!
//! # Pixel coordinates
//!
//! For a point that rsasim projects to continuous pixel coordinates (u, v) (pixel centres at
//! i + 0.5):
//! - OpenCV / MayaCam (0-based pixel centres, origin top-left of the exported image):
//!   x = u − 0.5, y = H − v − 0.5 ([`opencv_pixel`]).
//! - DLT-11 in the MATLAB/DLTdv convention XMALab exports (1-based, origin bottom-left):
//!   X = x + 1, Y = H − y, which is X = u + 0.5, Y = v + 0.5 ([`dlt_pixel`]).

use glam::{DMat3, DVec3};

use crate::expand::DetectorState;
use crate::geometry::rotation_rows;

/// A pinhole camera: `x_pixel ∝ K·(R·X + t)`, OpenCV conventions (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct PinholeCamera {
    /// Image width and height, pixels.
    pub size: [u32; 2],
    /// Intrinsic matrix K, rows: `[fx, 0, cx], [0, fy, cy], [0, 0, 1]`.
    pub k: [[f64; 3]; 3],
    /// World → camera rotation R, rows.
    pub r: [[f64; 3]; 3],
    /// World → camera translation t = −R·(source position), mm.
    pub t: [f64; 3],
}

/// OpenCV pixel coordinates (0-based pixel centres, exported image flipped) of rsasim's
/// continuous pixel coordinates `(u, v)` on an image `height` rows high.
pub fn opencv_pixel(uv: [f64; 2], height: u32) -> [f64; 2] {
    [uv[0] - 0.5, f64::from(height) - uv[1] - 0.5]
}

/// DLT-11 pixel coordinates (1-based, origin bottom-left of the exported image) of rsasim's
/// continuous pixel coordinates `(u, v)`.
pub fn dlt_pixel(uv: [f64; 2]) -> [f64; 2] {
    [uv[0] + 0.5, uv[1] + 0.5]
}

impl PinholeCamera {
    /// The camera of a beamline: a source (focus) at `source_mm` and its detector, both in the
    /// box frame. Errors when the source does not lie in front of the detector.
    pub fn of_beamline(
        source_mm: DVec3,
        detector: &DetectorState,
    ) -> Result<PinholeCamera, String> {
        let pose = detector.pose();
        let local = pose.to_local(source_mm);
        let d = local.z;
        if !(d > 0.0 && d.is_finite()) {
            return Err(format!(
                "the source of detector `{}` does not lie in front of it (distance to the detector plane {d} mm)",
                detector.id
            ));
        }
        let [w, h] = detector.pixels;
        let [px, py] = detector.pixel_pitch_mm;
        let (fx, fy) = (d / px, d / py);
        let cx = local.x / px + f64::from(w) / 2.0 - 0.5;
        let cy = f64::from(h) / 2.0 - local.y / py - 0.5;
        let rot = detector.rotation;
        let r_axis = rot.x_axis;
        let c_axis = rot.y_axis;
        let s_axis = rot.z_axis;
        // Rows of the world → camera rotation: the camera axes in world coordinates.
        let world_to_camera = DMat3::from_cols(r_axis, -c_axis, -s_axis).transpose();
        let t = -(world_to_camera * source_mm);
        let camera = PinholeCamera {
            size: [w, h],
            k: [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]],
            r: rotation_rows(&world_to_camera),
            t: t.to_array(),
        };
        camera.check_finite(&detector.id)?;
        Ok(camera)
    }

    /// Every number of the camera finite, so no NaN or infinity reaches a camera file: a source
    /// or detector far beyond any scene (1e308 mm), or a pixel pitch near zero, overflows.
    fn check_finite(&self, detector: &str) -> Result<(), String> {
        let numbers = self
            .k
            .iter()
            .chain(self.r.iter())
            .flatten()
            .chain(self.t.iter());
        if numbers.clone().all(|v| v.is_finite()) {
            return Ok(());
        }
        Err(format!(
            "the camera of detector `{}` is not finite (a source or detector position, or a pixel pitch, beyond what a scene can hold): {:?} {:?} {:?}",
            crate::diagnostic::cut(detector),
            self.k,
            self.r,
            self.t
        ))
    }

    /// The 3×4 projection matrix K·[R | t].
    pub fn projection(&self) -> [[f64; 4]; 3] {
        let mut p = [[0.0; 4]; 3];
        for (i, row) in p.iter_mut().enumerate() {
            for (j, cell) in row.iter_mut().enumerate() {
                *cell = (0..3)
                    .map(|m| {
                        let rt = if j < 3 { self.r[m][j] } else { self.t[m] };
                        self.k[i][m] * rt
                    })
                    .sum();
            }
        }
        p
    }

    /// The direction (box frame, not normalised) of the ray from the camera centre through the
    /// OpenCV pixel coordinates `xy`: Rᵀ·K⁻¹·(x, y, 1).
    pub fn ray_direction(&self, xy: [f64; 2]) -> DVec3 {
        let (k, r) = (&self.k, &self.r);
        let yn = (xy[1] - k[1][2]) / k[1][1];
        let xn = (xy[0] - k[0][2] - k[0][1] * yn) / k[0][0];
        let n = [xn, yn, 1.0];
        DVec3::new(
            (0..3).map(|i| r[i][0] * n[i]).sum(),
            (0..3).map(|i| r[i][1] * n[i]).sum(),
            (0..3).map(|i| r[i][2] * n[i]).sum(),
        )
    }

    /// OpenCV pixel coordinates of a box-frame point, or `None` behind the camera.
    pub fn project(&self, point_mm: DVec3) -> Option<[f64; 2]> {
        homogeneous(&self.projection(), point_mm)
    }

    /// The 11 DLT coefficients L1…L11 (L12 = 1) in XMALab's convention: 1-based pixels, origin
    /// bottom-left (see the module docs). Errors when L12 would be zero (the box origin lies in
    /// the plane of the source parallel to the detector).
    pub fn dlt(&self) -> Result<[f64; 11], String> {
        let p = self.projection();
        let h = f64::from(self.size[1]);
        // [X, Y, 1] = A·[x, y, 1] with A = [[1, 0, 1], [0, −1, H], [0, 0, 1]].
        let a = [[1.0, 0.0, 1.0], [0.0, -1.0, h], [0.0, 0.0, 1.0]];
        let mut q = [[0.0; 4]; 3];
        for (i, row) in q.iter_mut().enumerate() {
            for (j, cell) in row.iter_mut().enumerate() {
                *cell = (0..3).map(|m| a[i][m] * p[m][j]).sum();
            }
        }
        let l12 = q[2][3];
        if l12.abs() < 1e-12 * q[2][..3].iter().map(|v| v.abs()).sum::<f64>().max(1.0) {
            return Err("the box origin lies in the plane of the source parallel to the detector; DLT-11 (L12 = 1) cannot describe this camera".into());
        }
        let mut l = [0.0; 11];
        for (n, cell) in l.iter_mut().enumerate() {
            *cell = q[n / 4][n % 4] / l12;
        }
        if l.iter().any(|v| !v.is_finite()) {
            return Err(
                "the DLT-11 coefficients are not finite (the camera lies beyond what a scene can hold)"
                    .into(),
            );
        }
        Ok(l)
    }

    /// The MayaCam 2.0 text (what XMALab writes and XMALab and Autoscoper read): image size
    /// (width first), camera matrix, rotation, translation. Numbers are the shortest decimal
    /// that reads back as the same 64-bit float.
    pub fn mayacam_text(&self) -> String {
        let row3 = |r: &[f64; 3]| format!("{},{},{}\n", r[0], r[1], r[2]);
        let mut s = String::new();
        s += "image size\n";
        s += &format!("{},{}\n\n", self.size[0], self.size[1]);
        s += "camera matrix\n";
        self.k.iter().for_each(|r| s += &row3(r));
        s += "\nrotation\n";
        self.r.iter().for_each(|r| s += &row3(r));
        s += "\ntranslation\n";
        self.t.iter().for_each(|v| s += &format!("{v}\n"));
        s
    }

    /// Reads MayaCam 2.0 text as Autoscoper does, by line: 2 the size, 5–7 K, 10–12 R,
    /// 15–17 t (1-based). Errors give the 1-based line.
    pub fn parse_mayacam(text: &str) -> Result<PinholeCamera, (usize, String)> {
        let lines: Vec<&str> = text.lines().collect();
        let numbers = |line: usize, n: usize| -> Result<Vec<f64>, (usize, String)> {
            let l = lines
                .get(line - 1)
                .ok_or((line, "the file ends early".to_string()))?;
            let v: Vec<f64> = l
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| (line, format!("`{l}`: {e}")))?;
            if v.len() != n || v.iter().any(|x| !x.is_finite()) {
                return Err((line, format!("`{l}`: expected {n} finite numbers")));
            }
            Ok(v)
        };
        for (line, head) in [
            (1, "image size"),
            (4, "camera matrix"),
            (9, "rotation"),
            (14, "translation"),
        ] {
            if lines.get(line - 1).map(|l| l.trim()) != Some(head) {
                return Err((line, format!("expected `{head}`")));
            }
        }
        let size = numbers(2, 2)?;
        let m3 = |first: usize| -> Result<[[f64; 3]; 3], (usize, String)> {
            let mut m = [[0.0; 3]; 3];
            for (i, row) in m.iter_mut().enumerate() {
                let v = numbers(first + i, 3)?;
                row.copy_from_slice(&v);
            }
            Ok(m)
        };
        let k = m3(5)?;
        let r = m3(10)?;
        let mut t = [0.0; 3];
        for (i, v) in t.iter_mut().enumerate() {
            *v = numbers(15 + i, 1)?[0];
        }
        let dim =
            |x: f64| (x >= 1.0 && x.fract() == 0.0 && x <= f64::from(u32::MAX)).then_some(x as u32);
        let (Some(w), Some(h)) = (dim(size[0]), dim(size[1])) else {
            return Err((
                2,
                "the image size must be two positive whole numbers".into(),
            ));
        };
        Ok(PinholeCamera {
            size: [w, h],
            k,
            r,
            t,
        })
    }
}

/// The camera of every detector of `run` with its source position, in the run's detector order;
/// an error names a detector whose source is missing or lies behind it.
pub fn run_cameras(run: &crate::expand::Run) -> Result<Vec<(DVec3, PinholeCamera)>, String> {
    run.detectors
        .iter()
        .map(|d| {
            let source = run
                .sources
                .iter()
                .find(|s| s.id == d.source)
                .ok_or_else(|| format!("detector `{}` names no source of the run", d.id))?
                .position_mm;
            PinholeCamera::of_beamline(source, d).map(|c| (source, c))
        })
        .collect()
}

/// Projects a point with a 3×4 matrix; `None` when its third coordinate is not positive.
fn homogeneous(p: &[[f64; 4]; 3], x: DVec3) -> Option<[f64; 2]> {
    let v = |i: usize| p[i][0] * x.x + p[i][1] * x.y + p[i][2] * x.z + p[i][3];
    let w = v(2);
    (w > 0.0).then(|| [v(0) / w, v(1) / w])
}

/// Reprojects a box-frame point with DLT-11 coefficients (L12 = 1).
pub fn dlt_project(l: &[f64; 11], x: DVec3) -> [f64; 2] {
    let den = l[8] * x.x + l[9] * x.y + l[10] * x.z + 1.0;
    [
        (l[0] * x.x + l[1] * x.y + l[2] * x.z + l[3]) / den,
        (l[4] * x.x + l[5] * x.y + l[6] * x.z + l[7]) / den,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{rotation_from_rows, rotation_xyz_deg};

    fn detector(rotation: DMat3, position: DVec3) -> DetectorState {
        DetectorState {
            id: "det1".into(),
            source: "tube1".into(),
            position_mm: position,
            rotation,
            pixels: [640, 480],
            pixel_pitch_mm: [0.25, 0.2],
            bpp: 16,
        }
    }

    /// A tilted, off-centre beamline: every test point projects the same through rsasim's
    /// detector frame, the camera, the MayaCam text read back and the DLT.
    #[test]
    fn camera_mayacam_and_dlt_reproduce_rsasim_projection() {
        let det = detector(
            rotation_xyz_deg([3.0, -8.0, 21.0]),
            DVec3::new(12.0, -7.0, -480.0),
        );
        let source = DVec3::new(-20.0, 15.0, 1290.0);
        let cam = PinholeCamera::of_beamline(source, &det).unwrap();
        let back = PinholeCamera::parse_mayacam(&cam.mayacam_text()).unwrap();
        assert_eq!(back, cam, "MayaCam text reads back exactly");
        let dlt = cam.dlt().unwrap();
        let frame = det.frame();
        for p in [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(30.0, -12.0, 55.0),
            DVec3::new(-41.0, 27.5, -80.0),
        ] {
            let uv = frame.project(source, p).unwrap();
            let uv = [uv.x, uv.y];
            let cv = cam.project(p).unwrap();
            let want = opencv_pixel(uv, 480);
            assert!(
                (cv[0] - want[0]).abs() < 1e-9 && (cv[1] - want[1]).abs() < 1e-9,
                "{cv:?} {want:?}"
            );
            let d = dlt_project(&dlt, p);
            let want = dlt_pixel(uv);
            assert!(
                (d[0] - want[0]).abs() < 1e-9 && (d[1] - want[1]).abs() < 1e-9,
                "{d:?} {want:?}"
            );
        }
        // The ray through a point's pixel passes through the point.
        let p = DVec3::new(30.0, -12.0, 55.0);
        let d = cam.ray_direction(cam.project(p).unwrap()).normalize();
        assert!((p - source).cross(d).length() < 1e-9);
        // Positive focal lengths and a proper rotation.
        assert!(cam.k[0][0] > 0.0 && cam.k[1][1] > 0.0);
        let r = rotation_from_rows(cam.r);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_module_conventions_hold_by_hand() {
        // Detector at z = −500 facing +z, source 1800 mm above: the centre of the image lies on
        // the axis; f = 1800 / pitch.
        let det = detector(DMat3::IDENTITY, DVec3::new(0.0, 0.0, -500.0));
        let cam = PinholeCamera::of_beamline(DVec3::new(0.0, 0.0, 1300.0), &det).unwrap();
        assert_eq!(cam.k[0], [7200.0, 0.0, 319.5]);
        assert_eq!(cam.k[1], [0.0, 9000.0, 239.5]);
        assert_eq!(cam.r, [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]);
        assert_eq!(cam.t, [0.0, 0.0, 1300.0]);
        let text = cam.mayacam_text();
        assert!(
            text.starts_with("image size\n640,480\n\ncamera matrix\n7200,0,319.5\n"),
            "{text}"
        );
        assert_eq!(text.lines().count(), 17);
    }

    #[test]
    fn a_source_behind_the_detector_is_refused() {
        let det = detector(DMat3::IDENTITY, DVec3::ZERO);
        let e = PinholeCamera::of_beamline(DVec3::new(0.0, 0.0, -10.0), &det).unwrap_err();
        assert!(e.contains("det1") && e.contains("in front"), "{e}");
    }

    #[test]
    fn malformed_mayacam_names_the_line() {
        let det = detector(DMat3::IDENTITY, DVec3::new(0.0, 0.0, -500.0));
        let cam = PinholeCamera::of_beamline(DVec3::new(0.0, 0.0, 1300.0), &det).unwrap();
        let text = cam.mayacam_text().replace("0,9000,239.5", "0,9000,oops");
        assert_eq!(PinholeCamera::parse_mayacam(&text).unwrap_err().0, 6);
        let text = cam.mayacam_text().replace("rotation", "rot");
        assert_eq!(PinholeCamera::parse_mayacam(&text).unwrap_err().0, 9);
    }
}
