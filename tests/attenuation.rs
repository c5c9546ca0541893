//! Attenuation mode as a user meets it: pixel values that follow Beer–Lambert with the shipped
//! attenuation data along the exact chord, path-length truth, bead visibility, previews, and
//! clear refusals of scenes that cannot be simulated.

use crate::common;

use std::path::Path;

use common::{read_tiff, rsasim, truths};

/// One beamline along z: source 1000 mm above the origin, a 64 × 64 detector of 1 mm pitch
/// 200 mm below it; no randomisation.
const BEAMLINE: &str = r#"
[[sources]]
id = "tube"
position_mm = [0.0, 0.0, 1000.0]

[[detectors]]
id = "det"
source = "tube"
pixels = [64, 64]
pixel_pitch_mm = [1.0, 1.0]
bpp = 16
position_mm = [0.0, 0.0, -200.0]
"#;

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

/// A water cylinder of radius 40 mm along y at the origin, seen by a monochromatic 60 keV beam
/// of 10⁹ photons per pixel, photon counting with gain 10⁻⁵ (open field ≈ 10⁴, relative noise
/// 3·10⁻⁵).
fn water_cylinder(extra_imaging: &str) -> String {
    format!(
        r#"
name = "water"
[protocol]
runs_per_level = 1
[output]
formats = ["exr", "tiff"]
[imaging]
mode = "attenuation"
energy_kev = 60.0
photons_per_pixel = 1e9
{extra_imaging}
[imaging.detector]
response = "photon_counting"
gain = 1e-5
{BEAMLINE}
[[phantoms]]
id = "water"
rotation_deg = [-90.0, 0.0, 0.0]
material = "water"
elliptic_cylinder = {{ radii_mm = [40.0, 40.0], length_mm = 300.0 }}
[[exposures]]
id = "x"
phantoms = ["water"]
"#
    )
}

/// The chord of the ray from the source (0, 0, 1000) to the centre of pixel (i, j) through the
/// cylinder x² + z² ≤ 40² (axis along y), mm.
fn chord_mm(i: u32, j: u32) -> f64 {
    let s = [0.0, 0.0, 1000.0f64];
    let p = [i as f64 + 0.5 - 32.0, j as f64 + 0.5 - 32.0, -200.0];
    let d = [p[0] - s[0], p[1] - s[1], p[2] - s[2]];
    // Solve (s.x + t d.x)² + (s.z + t d.z)² = r² for t.
    let a = d[0] * d[0] + d[2] * d[2];
    let b = 2.0 * (s[0] * d[0] + s[2] * d[2]);
    let c = s[0] * s[0] + s[2] * s[2] - 1600.0;
    let disc = b * b - 4.0 * a * c;
    if disc <= 0.0 {
        return 0.0;
    }
    let (t0, t1) = (
        (-b - disc.sqrt()) / (2.0 * a),
        (-b + disc.sqrt()) / (2.0 * a),
    );
    (t1 - t0) * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// The open field of [`water_cylinder`] at pixel (i, j): 10⁴·(D/r)³ (inverse square and
/// obliquity), DN.
fn open_dn(i: u32, j: u32) -> f64 {
    let (x, y) = (i as f64 + 0.5 - 32.0, j as f64 + 0.5 - 32.0);
    let r = (x * x + y * y + 1200.0 * 1200.0).sqrt();
    1e4 * (1200.0 / r).powi(3)
}

/// [`water_cylinder`]'s expected value at pixel (i, j) by hand: the open field times
/// Beer–Lambert along the exact chord with the shipped μ of water at 60 keV, DN.
fn beer_lambert_dn(i: u32, j: u32) -> f64 {
    let mu_per_mm = rsasim::material::by_name("water")
        .unwrap()
        .linear_attenuation_per_mm(60.0);
    open_dn(i, j) * (-mu_per_mm * chord_mm(i, j)).exp()
}

/// Runs the scenario `text` (written as `name`.toml in `dir`) into `dir/name`; returns that
/// folder and its one image `x-det.tiff` (width, height, values).
fn run_water(dir: &Path, name: &str, text: &str) -> (std::path::PathBuf, u32, u32, Vec<u16>) {
    let scenario = write(dir, &format!("{name}.toml"), text);
    let out = dir.join(name);
    let o = rsasim(&[&scenario, "--out", out.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (w, h, px) = read_tiff(&out.join("runs/n0-r00/x-det.tiff"));
    (out, w, h, px)
}

#[test]
fn pixel_values_follow_beer_lambert_along_the_exact_chord() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, w, _, px) = run_water(tmp.path(), "out", &water_cylinder(""));
    let mut checked = 0;
    for j in [5u32, 32, 60] {
        for i in (0..64).step_by(3) {
            let v = f64::from(px[(j * w + i) as usize]);
            let expected = beer_lambert_dn(i, j);
            // Rounding to whole counts (±0.5) and noise (√(10⁹·T)·10⁻⁵) bound the difference.
            let tolerance = 0.5 + 5.0 * (expected * 1e-5).sqrt() + 1e-4 * expected;
            assert!(
                (v - expected).abs() <= tolerance,
                "pixel ({i}, {j}): {v} vs Beer–Lambert {expected:.2} (chord {:.3} mm)",
                chord_mm(i, j)
            );
            checked += 1;
        }
    }
    assert!(checked > 60);
    // Through the axis the chord is about 80 mm of water: well below the open field.
    assert!(f64::from(px[(32 * w + 32) as usize]) < 0.3 * open_dn(32, 32));
}

/// `quantum_noise = false`: every pixel of the water cylinder's image is Beer–Lambert along
/// the exact chord, by hand (inverse square, obliquity, the shipped μ), to the rounding of the
/// stored value; the same scene with quantum noise differs from it by the noise; each folder's
/// README says which images it holds and lists exposure factors.
#[test]
fn without_quantum_noise_every_pixel_is_beer_lambert_to_the_rounding() {
    let tmp = tempfile::tempdir().unwrap();
    let text = water_cylinder("").replace("gain = 1e-5\n", "gain = 1e-5\nquantum_noise = false\n");
    assert!(text.contains("quantum_noise = false"));
    let (out, w, h, px) = run_water(tmp.path(), "out", &text);
    let mut worst = 0.0f64;
    for j in 0..h {
        for i in 0..w {
            let v = f64::from(px[(j * w + i) as usize]);
            worst = worst.max((v - beer_lambert_dn(i, j)).abs());
        }
    }
    // Rounding to whole digital units, and the double arithmetic of the chord (≪ 10⁻⁶).
    assert!(
        worst <= 0.5 + 1e-6,
        "worst |stored − Beer–Lambert| {worst} DN"
    );
    // With quantum noise (√(10⁹) ≈ 3·10⁴ counts, times the gain 10⁻⁵: ≈ 0.3 DN) the
    // stored values differ from these in many pixels.
    let (noisy, _, _, noisy_px) = run_water(tmp.path(), "noisy", &water_cylinder(""));
    let differ = px.iter().zip(&noisy_px).filter(|(a, b)| a != b).count();
    assert!(
        differ > px.len() / 10,
        "{differ} of {} pixels differ",
        px.len()
    );
    // The folder's README says which images these are, and lists exposure factors, not the
    // binary mode's noise levels.
    let readme = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(
        readme.contains("expected images, without quantum noise"),
        "{readme}"
    );
    assert!(readme.contains("| run | exposure factor |\n| --- | --- |\n| `n0-r00` | 1 |"));
    assert!(!readme.contains("noise level"), "{readme}");
    let readme = std::fs::read_to_string(noisy.join("README.md")).unwrap();
    assert!(
        readme.contains("carry the quantum noise of their photons"),
        "{readme}"
    );
}

#[test]
fn path_length_layers_hold_the_exact_chord_and_are_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = write(
        tmp.path(),
        "water.toml",
        &water_cylinder("path_length_layers = true"),
    );
    let out = tmp.path().join("out");
    let o = rsasim(&[&scenario, "--out", out.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (_, truth) = &truths(&out)[0];
    let image = &truth.images[0];
    let file = image
        .path_lengths
        .as_ref()
        .expect("the path-length EXR is listed");
    let bytes = std::fs::read(out.join("runs/n0-r00").join(&file.path)).unwrap();
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .unwrap();
    let channel = &img.layer_data.channel_data.list[0];
    assert_eq!(channel.name.to_string(), "pathlength_mm.water");
    let values: Vec<f32> = channel.sample_data.values_as_f32().collect();
    for (i, j) in [(32u32, 32u32), (10, 5), (50, 60), (0, 0)] {
        let got = f64::from(values[(j * 64 + i) as usize]);
        assert!(
            (got - chord_mm(i, j)).abs() < 1e-4,
            "pixel ({i}, {j}): {got} vs {}",
            chord_mm(i, j)
        );
    }
    // Listed in the manifest like every file.
    let manifest = std::fs::read_to_string(out.join("manifest.json")).unwrap();
    assert!(manifest.contains(&format!("runs/n0-r00/{}", file.path)));
}

#[test]
fn golden_attenuation_scenario_reports_bead_visibility_and_previews() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = rsasim(
        &[
            "scenarios/golden/small_attenuation.toml",
            "--out",
            out.to_str().unwrap(),
            "--preview",
            "png",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let all = truths(&out);
    assert_eq!(all.len(), 4);
    let mut occluded = 0;
    let mut seen = 0;
    for (dir, t) in &all {
        assert!(t.run.exposure_factor.is_some());
        for image in &t.images {
            assert!(image.saturated_pixels.is_some());
            for m in &image.markers {
                let f = m
                    .metal_fraction
                    .expect("attenuation mode reports visibility");
                assert!((0.0..=1.0).contains(&f));
                seen += 1;
                occluded += usize::from(m.occluded.unwrap());
            }
            // The preview decodes as an 8-bit grey PNG of the image's size.
            let png = dir.join(format!("{}-{}.png", image.exposure, image.detector));
            let decoder =
                png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
            let reader = decoder.read_info().unwrap();
            assert_eq!(reader.info().width, 160);
        }
    }
    assert!(seen > 0);
    // The calibration beads never lie over metal.
    assert!(occluded < seen);
    // The images are not binary: many distinct values.
    let (_, _, px) = read_tiff(&all[0].0.join("model-det1.tiff"));
    let mut distinct = px.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert!(distinct.len() > 200, "{} distinct values", distinct.len());
}

#[test]
fn a_bead_across_a_surface_is_refused_before_anything_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let text = water_cylinder("").replace(
        "[[exposures]]",
        "[[phantoms]]\nid = \"beads\"\n[[phantoms.beads]]\nid = \"B1\"\nposition_mm = [0.0, 0.0, 39.8]\n[[exposures]]",
    );
    let text = text.replace(
        "phantoms = [\"water\"]",
        "phantoms = [\"water\", \"beads\"]",
    );
    let scenario = write(tmp.path(), "s.toml", &text);
    let o = rsasim(&["validate", &scenario], &[]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bead beads/B1 crosses the surface of water"),
        "{err}"
    );
    let out = tmp.path().join("out");
    let o = rsasim(&[&scenario, "--out", out.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!out.exists());
}

#[test]
fn a_solid_poking_out_of_the_one_it_is_inside_is_an_error_naming_both() {
    let tmp = tempfile::tempdir().unwrap();
    let text = water_cylinder("").replace(
        "[[exposures]]",
        "[[phantoms]]\nid = \"bone\"\nrotation_deg = [-90.0, 0.0, 0.0]\nmaterial = \"bone_cortical\"\ninside = \"water\"\nelliptic_cylinder = { radii_mm = [10.0, 50.0], length_mm = 100.0 }\n[[exposures]]",
    );
    let text = text.replace("phantoms = [\"water\"]", "phantoms = [\"water\", \"bone\"]");
    let scenario = write(tmp.path(), "s.toml", &text);
    let out = tmp.path().join("out");
    let o = rsasim(&[&scenario, "--out", out.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("not wholly inside") && err.contains("bone"),
        "{err}"
    );
    assert!(err.contains("nothing was written"), "{err}");
    assert!(!out.exists(), "nothing half-written is left");
}

#[test]
fn a_user_spectrum_travels_with_the_output_and_reconstruct_needs_a_calibration_box() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("measured.tsv"),
        "# a measured spectrum\nenergy_kev photons\n40 1\n50 3\n60 2\n",
    )
    .unwrap();
    let text = water_cylinder("").replace("energy_kev = 60.0", "spectrum_file = \"measured.tsv\"");
    let scenario = write(tmp.path(), "s.toml", &text);
    let out = tmp.path().join("out");
    let o = rsasim(&[&scenario, "--out", out.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read_to_string(out.join("phantoms/spectrum.tsv")).unwrap(),
        std::fs::read_to_string(tmp.path().join("measured.tsv")).unwrap()
    );
    // The output's own scenario stands alone.
    let o = rsasim(
        &["validate", out.join("scenario.toml").to_str().unwrap()],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The reference program reads attenuation images (tests/reconstruct_realistic.rs); with no
    // calibration box it says so and reconstructs nothing.
    let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no calibration box"), "{err}");
}

#[test]
fn bad_detector_blur_is_refused_naming_the_key() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = [
        (
            "psf = { sigma_mm = -0.1 }",
            "psf.sigma_mm",
            "PSF sigma -0.1 mm is out of range",
        ),
        (
            "psf = { sigma_mm = 0.1 }\nmtf = [[0.0, 1.0], [1.0, 0.5]]",
            "mtf",
            "psf or mtf, not both",
        ),
        (
            "mtf = [[0.5, 1.0], [1.0, 0.5]]",
            "mtf[0]",
            "the MTF starts at [0.5, 1]",
        ),
        (
            "mtf = [[0.0, 1.0], [2.0, 0.5], [1.0, 0.2]]",
            "mtf[2]",
            "MTF row 2 [1, 0.2] is not valid",
        ),
        (
            "scatter = { ratio = -0.2, sigma_mm = 40.0 }",
            "scatter.ratio",
            "scatter-to-primary ratio -0.2 is out of range",
        ),
        (
            "scatter = { ratio = 0.2, sigma_mm = 0.0 }",
            "scatter.sigma_mm",
            "scatter kernel sigma 0 mm is out of range",
        ),
        (
            "electronic_noise_dn = -1.0",
            "electronic_noise_dn",
            "electronic noise -1 DN is out of range",
        ),
    ];
    for (k, (line, key, message)) in cases.iter().enumerate() {
        let text = water_cylinder("").replace("gain = 1e-5", &format!("gain = 1e-5\n{line}"));
        let scenario = write(tmp.path(), &format!("s{k}.toml"), &text);
        let out = tmp.path().join(format!("out{k}"));
        let o = rsasim(&[&scenario, "--out", out.to_str().unwrap()], &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{line}: {err}");
        assert!(
            err.contains(&format!("imaging.detector.{key}")),
            "{line}: {err}"
        );
        assert!(err.contains(message), "{line}: {err}");
        assert!(
            err.contains(&format!("s{k}.toml:")),
            "names the file and line: {err}"
        );
        assert!(!out.exists(), "nothing written");
    }
}

#[test]
fn a_detector_psf_blurs_the_edges_and_keeps_the_signal() {
    // The water cylinder sharp and with a 2 mm Gaussian PSF (1 mm pixels): the blurred image has
    // the same total (the kernel is normalised, borders renormalised) and a smaller largest step
    // between neighbours across the cylinder's edge.
    let tmp = tempfile::tempdir().unwrap();
    let mut images = Vec::new();
    for (name, extra) in [("sharp", ""), ("blurred", "psf = { sigma_mm = 2.0 }")] {
        let text = water_cylinder("").replace("gain = 1e-5", &format!("gain = 1e-5\n{extra}"));
        let scenario = write(tmp.path(), &format!("{name}.toml"), &text);
        let out = tmp.path().join(name);
        let o = rsasim(&[&scenario, "--out", out.to_str().unwrap()], &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (w, _, px) =
            rsasim::output::decode::read_image(&out.join("runs/n0-r00"), "x-det").unwrap();
        images.push((px, w));
    }
    let total = |px: &[u16]| px.iter().map(|&v| f64::from(v)).sum::<f64>();
    let (sharp, blurred) = (&images[0].0, &images[1].0);
    let w = images[0].1 as usize;
    let ratio = total(blurred) / total(sharp);
    assert!((ratio - 1.0).abs() < 1e-3, "total changed by {ratio}");
    let max_step = |px: &[u16]| {
        let row = &px[32 * w..33 * w];
        row.windows(2)
            .map(|p| (f64::from(p[0]) - f64::from(p[1])).abs())
            .fold(0.0, f64::max)
    };
    assert!(
        max_step(blurred) < 0.8 * max_step(sharp),
        "{} vs {}",
        max_step(blurred),
        max_step(sharp)
    );
}
