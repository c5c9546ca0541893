//! The exports checked against the clients' own reading rules, each rule with the client's file
//! and function it comes from (XMALab: `XROMMPackages/xmalab`; Autoscoper:
//! `BrownBiomechanics/Autoscoper`, `libautoscoper/src/`). The rules are written out here from the
//! clients' code, not taken from rsasim's writers; volume tags are read by libtiff's `tiffinfo`
//! (the library Autoscoper reads volumes with), pixels by the `tiff` crate.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{export_ok, exported, numbers, read_tiff, rsasim, truths};
use rsasim::output::Truth;

/// Numbers of a space-separated `.cfg` value (`VoxelSize`, `VolumeFlip`, the offset comment).
fn words(value: &str) -> Vec<f64> {
    value
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect()
}

/// A MayaCam 2.0 camera read as the clients read it ([`common::read_mayacam`]: Autoscoper's
/// `Camera::loadMayaCam2` and XMALab's `ExternalCalibrationFrame` read the same lines).
/// `single`: every value rounded to a 32-bit float first, as XMALab's `fscanf("%f")` does.
struct MayaCam {
    size: [f64; 2],
    k: [[f64; 3]; 3],
    r: [[f64; 3]; 3],
    t: [f64; 3],
}

fn mayacam(file: &Path, single: bool) -> MayaCam {
    let (size, k, r, t) = common::read_mayacam(&std::fs::read_to_string(file).unwrap());
    let f = |v: f64| if single { f64::from(v as f32) } else { v };
    MayaCam {
        size: size.map(f),
        k: k.map(|row| row.map(f)),
        r: r.map(|row| row.map(f)),
        t: t.map(f),
    }
}

impl MayaCam {
    /// OpenCV pixel (0-based, origin top-left) of a world point.
    fn project(&self, x: [f64; 3]) -> [f64; 2] {
        let c: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| self.r[i][j] * x[j]).sum::<f64>() + self.t[i])
            .collect();
        let p: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| self.k[i][j] * c[j]).sum::<f64>())
            .collect();
        [p[0] / p[2], p[1] / p[2]]
    }

    /// Camera-frame depth of a world point, mm.
    fn depth(&self, x: [f64; 3]) -> f64 {
        (0..3).map(|j| self.r[2][j] * x[j]).sum::<f64>() + self.t[2]
    }
}

/// The truth pixel `(u, v)` (rsasim's, pixel centres at i + 0.5) as an OpenCV pixel of the
/// exported image, whose rows are flipped: x = u − 0.5, y = H − v − 0.5.
fn opencv(uv: [f64; 2], h: f64) -> [f64; 2] {
    [uv[0] - 0.5, h - uv[1] - 0.5]
}

/// The world (box-frame) centre of a bead of `truth`.
fn bead_world(truth: &Truth, phantom: &str, id: &str) -> [f64; 3] {
    truth
        .run
        .phantoms
        .iter()
        .find(|p| p.id == phantom)
        .unwrap()
        .markers
        .iter()
        .find(|b| b.id == id)
        .unwrap()
        .position_mm
        .to_array()
}

/// A `.cfg` as Autoscoper's `Trial::parse` splits it: `#` lines skipped, the key up to the first
/// space, the value the rest of the line.
fn cfg_entries(text: &str) -> Vec<(String, String)> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (k, v) = l.split_once(' ').unwrap_or((l, ""));
            (k.to_string(), v.to_string())
        })
        .collect()
}

fn values<'a>(entries: &'a [(String, String)], key: &str) -> Vec<&'a str> {
    entries
        .iter()
        .filter(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
        .collect()
}

fn have_tiffinfo() -> bool {
    let ok = Command::new("tiffinfo").output().is_ok();
    if !ok {
        common::skip("the libtiff checks (needs tiffinfo: apt-get install libtiff-tools)");
    }
    ok
}

/// Every page of a multi-page 16-bit TIFF, decoded.
fn read_pages(path: &Path) -> (u32, u32, Vec<Vec<u16>>) {
    let mut dec =
        tiff::decoder::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()))
            .unwrap();
    let (w, h) = dec.dimensions().unwrap();
    let mut pages = Vec::new();
    loop {
        assert_eq!(
            dec.dimensions().unwrap(),
            (w, h),
            "non uniform volume slices"
        );
        match dec.read_image().unwrap() {
            tiff::decoder::DecodingResult::U16(v) => pages.push(v),
            _ => panic!("{} is not 16-bit", path.display()),
        }
        if !dec.more_images() {
            break;
        }
        dec.next_image().unwrap();
    }
    (w, h, pages)
}

/// Volume and centroid of a closed triangle mesh (divergence theorem), mm³ and mm.
fn solid_centroid(vertices: &[[f64; 3]], triangles: &[[usize; 3]]) -> (f64, [f64; 3]) {
    let mut v6 = 0.0;
    let mut c = [0.0; 3];
    for t in triangles {
        let [a, b, d] = t.map(|i| vertices[i]);
        let det = a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0])
            + a[2] * (b[0] * d[1] - b[1] * d[0]);
        v6 += det;
        for k in 0..3 {
            c[k] += det * (a[k] + b[k] + d[k]) / 4.0;
        }
    }
    (v6 / 6.0, c.map(|x| x / v6))
}

/// A binary STL's triangles (vertices not shared).
fn read_stl(path: &Path) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let bytes = std::fs::read(path).unwrap();
    let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
    let mut v = Vec::with_capacity(3 * n);
    for f in 0..n {
        let at = 84 + 50 * f + 12;
        for k in 0..3 {
            let p = at + 12 * k;
            let x = |o: usize| {
                f64::from(f32::from_le_bytes(
                    bytes[p + o..p + o + 4].try_into().unwrap(),
                ))
            };
            v.push([x(0), x(4), x(8)]);
        }
    }
    let t = (0..n).map(|f| [3 * f, 3 * f + 1, 3 * f + 2]).collect();
    (v, t)
}

fn apply(m: &[f64], p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| m[4 * i] * p[0] + m[4 * i + 1] * p[1] + m[4 * i + 2] * p[2] + m[4 * i + 3])
}

/// The trials of an output as its export holds them: a run without a frame alone, in the
/// folder of its run id; the frames of a sequence (`truth.json`'s `frame`) together, in frame
/// order, in the folder of its sequence id. Sorted by folder.
fn trials(out: &Path) -> Vec<(String, Vec<Truth>)> {
    let mut by_folder: std::collections::BTreeMap<String, Vec<Truth>> = Default::default();
    for (_, truth) in truths(out) {
        let folder = truth
            .run
            .frame
            .as_ref()
            .map_or(truth.run.id.clone(), |f| f.sequence.clone());
        by_folder.entry(folder).or_default().push(truth);
    }
    for frames in by_folder.values_mut() {
        frames.sort_by_key(|t| t.run.frame.as_ref().map_or(0, |f| f.index));
    }
    by_folder.into_iter().collect()
}

/// The images of a camera folder as both clients take them, in their frame order: the files
/// whose extension starts with `tif`, hidden ones left out, sorted by name (Autoscoper:
/// `Video::Video`, `std::sort` of the paths; XMALab: `CameraBox`, `QStringList::sort`, the same
/// order for ASCII names).
fn client_frames(folder: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)
        .unwrap()
        .map(|f| f.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            let ext = name.rsplit_once('.').map_or("", |(_, e)| e);
            !name.starts_with('.') && ext.starts_with("tif")
        })
        .collect();
    files.sort();
    files
}

/// Whether the exported (16-bit, rows flipped) image `exported` is the run image `original`
/// of a detector with `i_max`, scaled to 0..65535 (`round(v · 65535 / I_max)`) and possibly
/// inverted, as the export's README states.
fn is_export_of(
    exported: &(u32, u32, Vec<u16>),
    original: &(u32, u32, Vec<u16>),
    i_max: u16,
) -> bool {
    let (w, h) = (original.0 as usize, original.1 as usize);
    if (exported.0, exported.1) != (original.0, original.1) {
        return false;
    }
    let scaled = |v: u16| ((u64::from(v) * 65535 + u64::from(i_max) / 2) / u64::from(i_max)) as u16;
    [false, true].iter().any(|&invert| {
        (0..h).all(|j| {
            (0..w).all(|i| {
                let v = original.2[(h - 1 - j) * w + i];
                let v = if invert { i_max - v } else { v };
                exported.2[j * w + i] == scaled(v)
            })
        })
    })
}

/// Every camera folder `<exposure>-<detector>` of a trial folder `trial` holds as many images as
/// the trial has `frames`, and the k-th image in the clients' order (`client_frames`) is frame
/// k's own image. Returns the images checked.
fn check_frame_order(out: &Path, trial: &Path, frames: &[Truth]) -> usize {
    let mut checked = 0;
    for image in &frames[0].images {
        let stem = format!("{}-{}", image.exposure, image.detector);
        let files = client_frames(&trial.join("images").join(&stem));
        assert_eq!(files.len(), frames.len(), "{stem}: one image per frame");
        for (file, truth) in files.iter().zip(frames) {
            let det = common::detector(truth, &image.detector);
            let original = read_tiff(
                &out.join("runs")
                    .join(&truth.run.id)
                    .join(format!("{stem}.tiff")),
            );
            assert!(
                is_export_of(&read_tiff(file), &original, det.i_max()),
                "{} is not frame {}'s image {stem}",
                file.display(),
                truth.run.id
            );
            checked += 1;
        }
    }
    checked
}

/// The rows of a `.tra` file as Autoscoper's `load_tracking_results` reads them: one a frame,
/// 16 comma-separated numbers each (the matrix, row by row).
fn tra_rows(file: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(file)
        .unwrap()
        .lines()
        .map(|l| {
            let m = numbers(l);
            assert_eq!(m.len(), 16, "{}", file.display());
            assert_eq!(&m[12..], &[0.0, 0.0, 0.0, 1.0]);
            m
        })
        .collect()
}

/// The worst distance (px) over the beads of `phantom` in the images of `exposure` of `truth`
/// between their truth pixels and their local positions taken to the volume frame (minus
/// `offset`), through the `.tra` row `m` and the `cameras` (in the detectors' order).
fn worst_bead_px(
    truth: &Truth,
    exposure: &str,
    phantom: &str,
    offset: &[f64],
    m: &[f64],
    cameras: &[MayaCam],
) -> f64 {
    let mut worst: f64 = 0.0;
    let ph = truth.run.phantoms.iter().find(|p| p.id == phantom).unwrap();
    for image in truth.images.iter().filter(|im| im.exposure == exposure) {
        let d = truth
            .run
            .detectors
            .iter()
            .position(|x| x.id == image.detector)
            .unwrap();
        for mk in image
            .markers
            .iter()
            .filter(|m| m.phantom == phantom && m.inside)
        {
            let local = ph
                .pose()
                .to_local(glam::DVec3::from_array(bead_world(truth, phantom, &mk.id)));
            let vol_p = [
                local.x - offset[0],
                local.y - offset[1],
                local.z - offset[2],
            ];
            let got = cameras[d].project(apply(m, vol_p));
            let want = opencv(mk.pixel, cameras[d].size[1]);
            worst = worst.max((got[0] - want[0]).hypot(got[1] - want[1]));
        }
    }
    worst
}

/// The voxels of a volume where Autoscoper puts them in its volume frame, voxel (c, r, p) at
/// (sx·(c′+½), sy·(H−½−r′), −sz·(p′+½)), c′ = fx ? W−1−c : c, … (`VolumeDescription::
/// VolumeDescription`, `RayCaster::setInvModelView`): the count of inside voxels and their
/// centroid.
fn voxel_centroid(volume: &Path, s: &[f64], flip: &[f64]) -> (usize, [f64; 3]) {
    let (w, h, pages) = read_pages(volume);
    let dpages = pages.len();
    let mut sum = [0.0; 3];
    let mut count = 0usize;
    for (p, page) in pages.iter().enumerate() {
        for r in 0..h as usize {
            for c in 0..w as usize {
                if page[r * w as usize + c] == 0 {
                    continue;
                }
                let cf = if flip[0] != 0.0 {
                    w as usize - 1 - c
                } else {
                    c
                } as f64;
                let rf = if flip[1] != 0.0 {
                    h as usize - 1 - r
                } else {
                    r
                } as f64;
                let pf = if flip[2] != 0.0 { dpages - 1 - p } else { p } as f64;
                let v = [
                    s[0] * (cf + 0.5),
                    s[1] * (f64::from(h) - 0.5 - rf),
                    -s[2] * (pf + 0.5),
                ];
                for k in 0..3 {
                    sum[k] += v[k];
                }
                count += 1;
            }
        }
    }
    (count, sum.map(|x| x / count.max(1) as f64))
}

/// Every Autoscoper rule on an export of `out` in `dest`: each trial against `Trial::validate`,
/// its camera folders in frame order, each volume placed by Autoscoper's formula and the truth
/// `.tra` (one line a frame: line k with frame k's truth), beads through the `.tra` and the
/// cameras, the volume's tags by libtiff. Returns the trials checked.
fn check_autoscoper(out: &Path, dest: &Path) -> usize {
    let mut trials_checked = 0;
    let mut worst_px: f64 = 0.0;
    for (folder, frames) in trials(out) {
        let run = dest.join(&folder);
        let truth = &frames[0];
        check_frame_order(out, &run, &frames);
        for exposure in &truth.run.exposures {
            let cfg_path = run.join(format!("{}.cfg", exposure.id));
            if !cfg_path.exists() {
                // Only exposures with a model get a trial: Autoscoper needs a volume.
                assert!(
                    !exposure
                        .phantoms
                        .iter()
                        .any(|p| dest.join(format!("volumes/{p}.tif")).exists()),
                    "{folder}: no trial for exposure {}",
                    exposure.id
                );
                continue;
            }
            trials_checked += 1;
            let text = std::fs::read_to_string(&cfg_path).unwrap();
            let e = cfg_entries(&text);
            // Trial::validate: ≥ 1 camera, as many CameraRootDir, ≥ 1 VolumeFile, as many
            // VoxelSize, MeshFile 0 or as many as the volumes.
            let cams = values(&e, "mayaCam_csv");
            let dirs = values(&e, "CameraRootDir");
            let vols = values(&e, "VolumeFile");
            let sizes = values(&e, "VoxelSize");
            let flips = values(&e, "VolumeFlip");
            let meshes = values(&e, "MeshFile");
            assert!(!cams.is_empty() && cams.len() == dirs.len());
            assert!(!vols.is_empty() && sizes.len() == vols.len());
            assert!(meshes.is_empty() || meshes.len() == vols.len());
            assert_eq!(values(&e, "Version"), ["1.2"]);
            // Version ≥ 1.1: paths relative to the cfg's folder, no leading '/', '/' separators.
            for p in cams.iter().chain(&dirs).chain(&vols).chain(&meshes) {
                assert!(!p.starts_with('/') && !p.contains('\\'), "{p}");
                assert!(run.join(p).exists(), "{p} of {}", cfg_path.display());
            }
            // Camera folders (Trial::loadVideos): the trial's frames are the most images of
            // any camera folder, each a frame of this trial.
            for d in &dirs {
                assert_eq!(client_frames(&run.join(d)).len(), frames.len(), "{d}");
            }
            // Cameras read as Autoscoper reads them, in the cfg's order: the detectors'.
            let cameras: Vec<MayaCam> = cams.iter().map(|c| mayacam(&run.join(c), false)).collect();
            // Each volume with its flip, voxel size, truth pose and the offset the cfg states.
            for (i, vol) in vols.iter().enumerate() {
                let phantom = Path::new(vol)
                    .file_stem()
                    .unwrap()
                    .to_string_lossy()
                    .to_string();
                let s = words(sizes[i]);
                assert_eq!(s.len(), 3);
                let flip = words(flips[i]);
                let offset: Vec<f64> = text
                    .lines()
                    .find_map(|l| l.strip_prefix(&format!("#   {phantom}: offset ")))
                    .map(words)
                    .unwrap();
                // One line a frame (AutoscoperMainWindow::load_tracking_results reads line k
                // as frame k).
                let rows = tra_rows(&run.join(format!("truth/{}_{phantom}.tra", exposure.id)));
                assert_eq!(rows.len(), frames.len(), "one line a frame");
                // The volume and the mesh Autoscoper pairs with it, in the volume frame.
                let (count, c_vol) = voxel_centroid(&run.join(vol), &s, &flip);
                assert!(count > 0, "an empty volume makes Autoscoper exit");
                let (mv, mt) = read_stl(&run.join(meshes[i]));
                let (_, c_mesh_vol) = solid_centroid(&mv, &mt);
                // The model in its own frame, as the export also writes it (models/).
                let (verts, tris) = read_stl(&run.join(format!("models/{phantom}.stl")));
                let (volume_mm3, c_local) = solid_centroid(&verts, &tris);
                let rel = (count as f64 * s[0] * s[1] * s[2] - volume_mm3).abs() / volume_mm3;
                assert!(rel < 0.03, "voxel volume off by {rel}");
                for (m, frame) in rows.iter().zip(&frames) {
                    // Beads of the phantom: local (truth pose) → volume frame (minus the
                    // offset) → the frame's .tra line → every camera: on the truth pixel.
                    worst_px = worst_px.max(worst_bead_px(
                        frame,
                        &exposure.id,
                        &phantom,
                        &offset,
                        m,
                        &cameras,
                    ));
                    // The voxels' centroid moved by the line against the posed mesh's.
                    let ph = frame.run.phantoms.iter().find(|p| p.id == phantom).unwrap();
                    let c_world = ph.pose().to_world(glam::DVec3::from_array(c_local));
                    let voxel_world = glam::DVec3::from_array(apply(m, c_vol));
                    let off = (voxel_world - c_world).length();
                    eprintln!(
                        "{} {phantom}: {count} voxels ({:.0} mm³ against the mesh's {volume_mm3:.0}), centroid {off:.4} mm from the posed mesh's",
                        frame.run.id,
                        count as f64 * s[0] * s[1] * s[2]
                    );
                    // Voxelization moves the centroid by a discretization error (measured
                    // 0.074 mm at 0.5 mm voxels, 0.014 mm at 0.25 mm, 0.14 mm at 1 mm); a frame
                    // off by half a voxel along any axis would move it by 0.25 mm.
                    assert!(off < 0.25 * s[0], "voxel centroid {off} mm from the mesh's");
                    // The mesh moved by the same line: the posed mesh (f32 vertices: within
                    // 1e-3 mm).
                    let moved = glam::DVec3::from_array(apply(m, c_mesh_vol));
                    assert!((moved - c_world).length() < 1e-3, "{moved} {c_world}");
                }
            }
        }
    }
    eprintln!("{trials_checked} trials; worst bead reprojection through the .tra {worst_px:e} px");
    assert!(worst_px <= 1e-6, "{worst_px} px");
    // libtiff (Autoscoper's reader) on every volume: one sample, 16 bits, unsigned, MinIsBlack,
    // contiguous, a compression libtiff decodes (Volume::Volume, tiffImageRead).
    let volumes: Vec<PathBuf> = std::fs::read_dir(dest.join("volumes"))
        .unwrap()
        .map(|f| f.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "tif"))
        .collect();
    assert!(!volumes.is_empty());
    if !have_tiffinfo() {
        return trials_checked;
    }
    for volume in volumes {
        let o = Command::new("tiffinfo").arg(&volume).output().unwrap();
        let info = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{info}");
        let dirs = info.matches("TIFF Directory at offset").count();
        assert!(dirs > 10, "{dirs} pages");
        for (needle, n) in [
            ("Bits/Sample: 16", dirs),
            ("Samples/Pixel: 1", dirs),
            ("Sample Format: unsigned integer", dirs),
            ("Photometric Interpretation: min-is-black", dirs),
            ("Planar Configuration: single image plane", dirs),
            ("Compression Scheme: LZW", dirs),
        ] {
            assert_eq!(info.matches(needle).count(), n, "{needle}\n{info}");
        }
    }
    trials_checked
}

#[test]
fn autoscoper_trials_pass_trial_validate_and_the_truth_puts_volumes_and_beads_in_place() {
    let (_tmp, out, dest) = exported("scenarios/golden/small_biplanar.toml", "autoscoper", &[]);
    assert!(check_autoscoper(&out, &dest) >= 4);
}

/// The box beads in the first frame (by the clients' order) of the exported (flipped, 16-bit)
/// images of an exposure holding the box, against the trial's first `truth`: the mean value at
/// the centre pixels of those on the image and not over an implant, and the image's median.
fn bead_against_background(trial: &Path, truth: &Truth) -> (f64, u16) {
    let cal = truth
        .run
        .phantoms
        .iter()
        .find(|p| p.kind == "calibration_box")
        .unwrap();
    let image = truth
        .images
        .iter()
        .find(|im| {
            truth
                .run
                .exposures
                .iter()
                .any(|e| e.id == im.exposure && e.phantoms.contains(&cal.id))
        })
        .unwrap();
    let stem = format!("{}-{}", image.exposure, image.detector);
    let (w, h, px) = read_tiff(&client_frames(&trial.join(format!("images/{stem}")))[0]);
    // Row v of rsasim's image is row H − 1 − v of the export.
    let at: Vec<f64> = image
        .markers
        .iter()
        .filter(|m| m.phantom == cal.id && m.inside && m.occluded != Some(true))
        .map(|m| {
            let (i, j) = (m.pixel[0] as usize, h as usize - 1 - m.pixel[1] as usize);
            f64::from(px[j * w as usize + i])
        })
        .collect();
    assert!(!at.is_empty());
    let mut sorted = px.clone();
    sorted.sort_unstable();
    (
        at.iter().sum::<f64>() / at.len() as f64,
        sorted[sorted.len() / 2],
    )
}

/// Every XMALab rule on an export of `out` in `dest` (dense matter `bright` or dark): each
/// trial's camera folders in frame order, the calibration object where written (frame
/// specification header and rows, references and their rule, through the cameras as XMALab
/// reads them), its absence named in the export's README otherwise, and the beads' shade.
/// Returns the trials with a calibration object.
fn check_xmalab(out: &Path, dest: &Path, bright: bool) -> usize {
    let readme = std::fs::read_to_string(dest.join("README.md")).unwrap();
    let mut with_object = 0;
    for (folder, frames) in trials(out) {
        let trial = dest.join(&folder);
        let truth = &frames[0];
        check_frame_order(out, &trial, &frames);
        // Beads dark on the exported images by default, bright when asked.
        let (bead, background) = bead_against_background(&trial, truth);
        assert_eq!(
            bead > f64::from(background),
            bright,
            "{folder}: beads {bead}, background {background}"
        );
        let cal = trial.join("calibration");
        if !cal.join("references.ref").exists() {
            // Then no calibration object at all, and the README says why.
            assert!(!cal.join("frame_specification.csv").exists());
            let what = if truth.run.frame.is_some() {
                "sequence"
            } else {
                "run"
            };
            assert!(
                readme.contains(&format!("  - {what} {folder}: no four reference beads")),
                "{readme}"
            );
            continue;
        }
        with_object += 1;
        let spec = std::fs::read_to_string(cal.join("frame_specification.csv")).unwrap();
        let mut lines = spec.lines();
        // CalibrationObject::loadCoords: a header line; "white" in it switches to white blobs.
        assert_eq!(lines.next().unwrap().contains("white"), bright);
        // Then `x,y,z` per bead, read as numbers separated by commas.
        let box_phantom = truth
            .run
            .phantoms
            .iter()
            .find(|p| p.kind == "calibration_box")
            .unwrap();
        let beads: Vec<[f64; 3]> = lines
            .map(|l| <[f64; 3]>::try_from(numbers(l)).unwrap())
            .collect();
        assert_eq!(beads.len(), box_phantom.markers.len());
        // The references (`%i %20[0-9a-zA-Z ]s`, 1-based), in a `.ref` file (the dialog's filter).
        let refs = std::fs::read_to_string(cal.join("references.ref")).unwrap();
        let chosen: Vec<usize> = refs
            .lines()
            .map(|l| {
                let (i, name) = l.split_once(' ').unwrap();
                assert!(
                    !name.is_empty()
                        && name.len() <= 20
                        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == ' '),
                    "{l}"
                );
                i.parse::<usize>().unwrap() - 1
            })
            .collect();
        assert_eq!(chosen.len(), 4);
        assert!(chosen.iter().all(|&i| i < beads.len()));
        // Not coplanar: the tetrahedron holds at least 5 % of the beads' bounding box.
        let p: Vec<[f64; 3]> = chosen.iter().map(|&i| beads[i]).collect();
        let d = |a: [f64; 3], b: [f64; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let (u, v, w) = (d(p[0], p[1]), d(p[0], p[2]), d(p[0], p[3]));
        let vol = (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
            + u[2] * (v[0] * w[1] - v[1] * w[0]))
            .abs()
            / 6.0;
        let ext: Vec<f64> = (0..3)
            .map(|k| {
                let (lo, hi) = beads.iter().fold((f64::MAX, f64::MIN), |(lo, hi), b| {
                    (lo.min(b[k]), hi.max(b[k]))
                });
                hi - lo
            })
            .collect();
        assert!(vol >= 0.05 * ext[0] * ext[1] * ext[2], "{vol}");
        // In every view, through the cameras as XMALab reads them (32-bit floats): each
        // reference on the image and at least 3 bead diameters from every other bead's image.
        for det in &truth.run.detectors {
            let cam = mayacam(&cal.join(format!("{}_MayaCam.txt", det.id)), true);
            let bead_mm = box_phantom.markers[0].diameter_mm;
            let diameter_px = |x: [f64; 3]| cam.k[0][0] * bead_mm / cam.depth(x);
            for &r in &chosen {
                let c = cam.project(beads[r]);
                let own = diameter_px(beads[r]);
                // On the image, 3 of its diameters from the border (pixel centres at i, edges
                // at i ± 0.5).
                let m = 3.0 * own;
                assert!(
                    c[0] + 0.5 >= m * (1.0 - 1e-6)
                        && c[1] + 0.5 >= m * (1.0 - 1e-6)
                        && cam.size[0] - (c[0] + 0.5) >= m * (1.0 - 1e-6)
                        && cam.size[1] - (c[1] + 0.5) >= m * (1.0 - 1e-6),
                    "{}: reference {r} at {c:?}",
                    det.id
                );
                for (o, b) in beads.iter().enumerate().filter(|(o, _)| *o != r) {
                    let q = cam.project(*b);
                    let apart = (q[0] - c[0]).hypot(q[1] - c[1]);
                    assert!(
                        apart >= 3.0 * own.max(diameter_px(*b)) * (1.0 - 1e-6),
                        "{}: reference {r} {apart} px from bead {o}",
                        det.id
                    );
                }
            }
        }
    }
    with_object
}

#[test]
fn xmalab_calibration_object_follows_xmalabs_reading_rules_and_beads_are_dark() {
    let (_tmp, out, dest) = exported("tests/scenarios/xmalab_cube.toml", "xmalab", &[]);
    assert_eq!(check_xmalab(&out, &dest, false), 4);
    // --dense-matter bright: bright beads, and the header says "white".
    let (_tmp2, out2, dest2) = exported(
        "tests/scenarios/xmalab_cube.toml",
        "xmalab",
        &["--dense-matter", "bright"],
    );
    assert_eq!(check_xmalab(&out2, &dest2, true), 4);
}

#[test]
fn a_box_with_no_four_references_is_named_and_required_makes_it_an_error() {
    // The paper's cube seen square-on: every plate is edge-on in one of the two views.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    common::run_scenario("scenarios/golden/small_biplanar.toml", &out, &[]);
    let dest = tmp.path().join("x");
    let args = |extra: &'static str| {
        vec![
            "export".to_string(),
            out.to_string_lossy().to_string(),
            "--to".into(),
            "xmalab".into(),
            "--dir".into(),
            dest.to_string_lossy().to_string(),
            "--calibration-object".into(),
            extra.into(),
        ]
    };
    let run = |a: Vec<String>| rsasim(&a.iter().map(String::as_str).collect::<Vec<_>>(), &[]);
    let o = run(args("required"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("truth.json") && err.contains("no four reference beads"),
        "{err}"
    );
    assert!(!dest.exists(), "nothing written");
    let o = run(args("when-possible"));
    assert!(o.status.success());
    let note = String::from_utf8_lossy(&o.stderr);
    assert!(note.contains("not written for 4 of 4 run(s)"), "{note}");
    assert!(!dest.join("n0-r00/calibration/references.ref").exists());
    assert!(dest.join("n0-r00/calibration/det1_MayaCam.txt").exists());
}

/// Every bead image of every frame of `out` through the cameras of its trial in the export
/// `dest` as XMALab reads them (32-bit floats): (bead images, worst distance to the truth pixel
/// in px).
fn through_float32_cameras(out: &Path, dest: &Path) -> (usize, f64) {
    let mut worst: f64 = 0.0;
    let mut n = 0;
    for (folder, frames) in trials(out) {
        // One calibration a trial: every frame's beads through it.
        for truth in &frames {
            for image in &truth.images {
                let cam = mayacam(
                    &dest
                        .join(&folder)
                        .join(format!("calibration/{}_MayaCam.txt", image.detector)),
                    true,
                );
                for mk in image.markers.iter().filter(|m| m.inside) {
                    let got = cam.project(bead_world(truth, &mk.phantom, &mk.id));
                    let want = opencv(mk.pixel, cam.size[1]);
                    worst = worst.max((got[0] - want[0]).hypot(got[1] - want[1]));
                    n += 1;
                }
            }
        }
    }
    (n, worst)
}

/// One run of every shipped scenario (`--shard 0/N` with N above its runs), exported for both
/// programs, passes every check above. The cameras read as 32-bit floats stay within 1e-4 px on
/// the paper's 1440² biplanar set-up; the uniplanar ones (tubes 20° off the detector normal, the
/// principal point far off the image, f ≈ 4700 px) within 1e-3 px: a float's rounding of a
/// rotation entry near 1 (6e-8) times the focal length is already 3e-4 px there.
#[test]
fn every_shipped_scenario_exports_as_the_clients_read() {
    let mut scenarios: Vec<PathBuf> = std::fs::read_dir(common::root().join("scenarios"))
        .unwrap()
        .map(|f| f.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    scenarios.sort();
    assert!(scenarios.len() >= 7, "{scenarios:?}");
    for scenario in scenarios {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("out");
        let o = rsasim(
            &[
                scenario.to_str().unwrap(),
                "--shard",
                "0/100000",
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let shard = std::fs::read_dir(&out)
            .unwrap()
            .next()
            .unwrap()
            .unwrap()
            .path();
        let export = |to: &str| {
            let dest = tmp.path().join(to);
            export_ok(&shard, to, &dest, &[]);
            dest
        };
        let xma = export("xmalab");
        let cube = check_xmalab(&shard, &xma, false);
        let (n, worst) = through_float32_cameras(&shard, &xma);
        let trials = check_autoscoper(&shard, &export("autoscoper"));
        eprintln!(
            "{}: XMALab calibration object in {cube} run(s); {n} bead images through 32-bit cameras, worst {worst:e} px; {trials} Autoscoper trial(s)",
            scenario.file_name().unwrap().to_string_lossy()
        );
        assert!(n > 0 && trials > 0);
        let square_1440 = truths(&shard)[0]
            .1
            .run
            .detectors
            .iter()
            .all(|d| d.pixels == [1440, 1440]);
        let bound = if square_1440 { 1e-4 } else { 1e-3 };
        assert!(worst <= bound, "{worst} px (bound {bound})");
    }
}

/// The folders of an export besides README.md and volumes/: its trials.
fn trial_folders(dest: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dest)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "README.md" && n != "volumes")
        .collect();
    names.sort();
    names
}

/// A dynamic exam (tests/scenarios/sequence.toml: one sequence of 5 frames, the femur flexing)
/// exported for both programs passes the same client checks as a static export: one trial,
/// named by the sequence, whose camera folders hold its 5 frames in the clients' order, whose
/// one calibration puts every frame's beads on their truth pixels, and whose truth `.tra` has a
/// line a frame, each putting the volume and the beads on that frame's truth pixels.
#[test]
fn a_sequence_exports_as_one_trial_the_clients_read_frame_by_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    common::run_scenario("tests/scenarios/sequence.toml", &out, &[]);
    assert_eq!(truths(&out).len(), 5);
    let xma = tmp.path().join("xmalab");
    export_ok(&out, "xmalab", &xma, &[]);
    assert_eq!(trial_folders(&xma), ["n0-r00"]);
    // The box seen square-on by both views, as the paper's: no calibration object, and the
    // README names the sequence.
    assert_eq!(check_xmalab(&out, &xma, false), 0);
    let (n, worst) = through_float32_cameras(&out, &xma);
    assert!(n >= 5 * 6 * 2, "{n} bead images");
    assert!(worst <= 1e-4, "{worst} px");
    let asc = tmp.path().join("autoscoper");
    export_ok(&out, "autoscoper", &asc, &[]);
    assert_eq!(trial_folders(&asc), ["n0-r00"]);
    assert_eq!(check_autoscoper(&out, &asc), 1);
}

/// A shard holding frames 0, 2 and 4 of the sequence exports those as the sequence's trial,
/// numbered by frame (`.0001`, `.0003`, `.0005`: name order is still frame order), its `.tra`
/// a line each; the note and the README say which frames are missing. The client checks pass
/// with the trial's k-th frame the shard's k-th.
#[test]
fn a_shard_of_a_sequence_exports_the_frames_it_holds_numbered_by_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = rsasim(
        &[
            "tests/scenarios/sequence.toml",
            "--shard",
            "0/2",
            "--out",
            out.to_str().unwrap(),
            common::ALLOW_MODELS[0],
            common::ALLOW_MODELS[1],
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let shard = out.join("shard-0-of-2");
    let ids: Vec<String> = truths(&shard).into_iter().map(|t| t.1.run.id).collect();
    assert_eq!(ids, ["n0-r00-f0000", "n0-r00-f0002", "n0-r00-f0004"]);
    let asc = tmp.path().join("autoscoper");
    let note = export_ok(&shard, "autoscoper", &asc, &[]);
    assert!(
        note.contains("sequence n0-r00 has 5 frames, of which this output holds 3"),
        "{note}"
    );
    let readme = std::fs::read_to_string(asc.join("README.md")).unwrap();
    assert!(readme.contains("holds only some frames"), "{readme}");
    let names: Vec<String> = client_frames(&asc.join("n0-r00/images/model-det1"))
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "model-det1.0001.tif",
            "model-det1.0003.tif",
            "model-det1.0005.tif"
        ]
    );
    assert_eq!(check_autoscoper(&shard, &asc), 1);
    let xma = tmp.path().join("xmalab");
    export_ok(&shard, "xmalab", &xma, &[]);
    check_xmalab(&shard, &xma, false);
}

#[test]
fn a_voxel_size_that_gives_no_volume_is_refused_before_anything_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    common::run_scenario("scenarios/golden/small_biplanar.toml", &out, &[]);
    let dest = tmp.path().join("a");
    for (voxel, says) in [
        ("0", "not positive and finite"),
        ("NaN", "not positive and finite"),
        ("0.001", "more than 268435456"),
        ("1000", "no voxel centre"),
    ] {
        let o = rsasim(
            &[
                "export",
                out.to_str().unwrap(),
                "--to",
                "autoscoper",
                "--dir",
                dest.to_str().unwrap(),
                "--voxel-mm",
                voxel,
            ],
            &[],
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{voxel}: {err}");
        assert!(
            err.contains("scenario.toml") && err.contains("phantom `femur`") && err.contains(says),
            "{voxel}: {err}"
        );
        assert!(!dest.exists(), "{voxel}: nothing written");
    }
}
