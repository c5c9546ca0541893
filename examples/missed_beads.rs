//! Every box bead the reference program's detector misses or misplaces, classified (issue 32):
//! the detector (`rsasim::reconstruct::beads::find_beads`, with the metal mask the program uses)
//! runs on every image of an exposure holding the calibration box, and each box bead that the
//! truth puts on the image, not over an implant, is looked for within 1 px of its truth pixel.
//!
//! ```text
//! cargo run --release --example missed_beads -- OUT [--list]
//! ```
//!
//! A missed bead is put in the first class that fits:
//! - **overlap**: another bead's image within two bead-image diameters, counted apart within
//!   2.5 radii (the discs touch or overlap, and blur joins them) and from 2.5 to 4 radii;
//! - **plate edge**: the edge of a plate with a thickness (its outline projected) within the
//!   detector's window around the bead (radius + 4 px);
//! - **border**: the window reaches off the image;
//! - **other**: none of these. The detector is asked what it sees there
//!   ([`rsasim::reconstruct::beads::probe`]: the pixel of the strongest matched-filter response
//!   within 1.5 px of the truth pixel), and the miss is put under the test that rejects that
//!   candidate: **threshold** (signal-to-noise below the detector's), **local maximum** (a
//!   stronger response within the bead's box), **metal**, **shape** (no background, no peak, or a
//!   half-maximum region running out of the window), **centre** (the centroid or the Gaussian fit
//!   drifts off the candidate), or **found off** (a blob is reported, more than 1 px away).
//!
//! With `--list`, every "other" miss follows the table, one line each: run, detector, bead,
//! truth pixel, the nearest other bead's distance, the candidate's signal-to-noise, response,
//! ring background and tile noise (attenuation), and the test that rejects it.
//!
//! A found bead is **misplaced** when its centre is more than 0.25 px from the truth pixel; the
//! table gives the root mean square of the found beads' centre errors too.
//! Prints a Markdown table per exposure level, stamped with the output's program.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::ExitCode;

use glam::{DVec2, DVec3};
use rsasim::geometry::Pose;
use rsasim::output::Truth;
use rsasim::output::decode::read_image;
use rsasim::output::exam::load_setup;
use rsasim::reconstruct::beads::{Probe, Rejection, find_beads, metal_mask, probe};
use rsasim::reconstruct::density::{Reading, density};
use rsasim::reconstruct::pipeline::METAL_BEAD_AREAS;

#[derive(Default)]
struct Tally {
    beads: usize,
    found: usize,
    misplaced: usize,
    /// Sum of the squared centre errors of the beads found, px².
    squared_error_px2: f64,
    /// Overlaps by the nearest other bead's distance: within 2.5 bead-image radii (the discs
    /// touch or overlap, blurred), and 2.5 to 4 radii.
    overlap: [usize; 2],
    /// Of the overlaps, beads on a plate the view sees within 45° of edge-on.
    overlap_edge_on: [usize; 2],
    plate_edge: usize,
    border: usize,
    /// The other misses, by the test that rejects them.
    other: BTreeMap<Cause, usize>,
}

/// Why the detector misses a bead that no neighbour, plate edge or border explains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Cause {
    Threshold,
    LocalMaximum,
    Metal,
    Shape,
    Centre,
    FoundOff,
}

impl Cause {
    const ALL: [Cause; 6] = [
        Cause::Threshold,
        Cause::LocalMaximum,
        Cause::Metal,
        Cause::Shape,
        Cause::Centre,
        Cause::FoundOff,
    ];

    /// The cause of a miss where the detector sees `probe` (`None`: no pixel's ring fits in the
    /// image, so the window holds no bead: counted with the shapes).
    fn of(probe: Option<&Probe>) -> Cause {
        match probe.map(|p| p.verdict.as_ref().err()) {
            None => Cause::Shape,
            Some(None) => Cause::FoundOff,
            Some(Some(Rejection::Threshold)) => Cause::Threshold,
            Some(Some(Rejection::NotLocalMax)) => Cause::LocalMaximum,
            Some(Some(Rejection::Metal)) => Cause::Metal,
            Some(Some(Rejection::Background | Rejection::NoPeak | Rejection::Shape)) => {
                Cause::Shape
            }
            Some(Some(Rejection::Centroid | Rejection::GaussianFit | Rejection::SphereFit)) => {
                Cause::Centre
            }
        }
    }

    fn name(self) -> &'static str {
        match self {
            Cause::Threshold => "threshold",
            Cause::LocalMaximum => "local maximum",
            Cause::Metal => "metal",
            Cause::Shape => "shape",
            Cause::Centre => "centre",
            Cause::FoundOff => "found off",
        }
    }
}

/// One "other" miss as a line of the `--list` table.
fn list_row(
    run: &str,
    detector: &str,
    bead: &str,
    at: DVec2,
    neighbour_px: f64,
    seen: Option<&Probe>,
) -> String {
    let what = match seen {
        None => " |  |  |  |  | no pixel whose ring fits".to_string(),
        Some(p) => format!(
            "({}, {}) | {:.1} | {:.3} | {:.3} | {:.4} | {}",
            p.pixel[0],
            p.pixel[1],
            p.snr,
            p.contrast,
            p.background,
            p.noise_sd,
            match &p.verdict {
                Ok(b) => format!("blob at ({:.2}, {:.2})", b.centroid.x, b.centroid.y),
                Err(r) => format!("{r:?}"),
            }
        ),
    };
    format!(
        "| {run} | {detector} | {bead} | ({:.2}, {:.2}) | {neighbour_px:.2} | {what} |",
        at.x, at.y
    )
}

/// Distance from `p` to the segment `a`–`b`.
fn to_segment(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    (a + ab * t - p).length()
}

fn main() -> ExitCode {
    let list = std::env::args().any(|a| a == "--list");
    let Some(out) = std::env::args().skip(1).find(|a| a != "--list") else {
        eprintln!("usage: missed_beads OUT [--list]");
        return ExitCode::from(2);
    };
    let out = Path::new(&out);
    let setup = match load_setup(out) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e:?}");
            return ExitCode::from(2);
        }
    };
    let mut by_level: BTreeMap<String, Tally> = BTreeMap::new();
    let mut runs: Vec<_> = std::fs::read_dir(out.join("runs"))
        .expect("OUT/runs")
        .map(|e| e.unwrap().path())
        .collect();
    runs.sort();
    let mut program = String::new();
    let mut listed: Vec<String> = Vec::new();
    for dir in runs {
        let truth: Truth =
            serde_json::from_slice(&std::fs::read(dir.join("truth.json")).unwrap()).unwrap();
        program = truth.program.clone();
        let level = truth
            .run
            .exposure_factor
            .map_or(format!("noise {}", truth.run.noise_level), |f| {
                format!("×{f}")
            });
        let tally = by_level.entry(level).or_default();
        let Some(cal) = truth
            .run
            .phantoms
            .iter()
            .find(|p| p.kind == "calibration_box")
        else {
            continue;
        };
        // Each plate's normal (world), by plate id: bead ids are `<plate>-<row>-<column>`.
        let normals: Vec<(String, DVec3)> = setup
            .scenario
            .phantoms
            .iter()
            .filter(|p| p.id == cal.id)
            .filter_map(|p| p.calibration_box.as_ref())
            .flat_map(|b| b.plates.iter())
            .map(|p| {
                let pose = Pose::from_position_euler_deg(p.center_mm, p.rotation_deg);
                (p.id.clone(), cal.rotation * (pose.rotation * DVec3::Z))
            })
            .collect();
        // Plate outlines with a thickness, box frame → world by the box's pose.
        let plates: Vec<[DVec3; 4]> = setup
            .scenario
            .phantoms
            .iter()
            .filter(|p| p.id == cal.id)
            .filter_map(|p| p.calibration_box.as_ref())
            .flat_map(|b| b.plates.iter())
            .filter(|p| p.thickness_mm.is_some())
            .map(|p| {
                let pose = Pose::from_position_euler_deg(p.center_mm, p.rotation_deg);
                let [sx, sy] = p.size_mm.map(|s| s / 2.0);
                [(-sx, -sy), (sx, -sy), (sx, sy), (-sx, sy)]
                    .map(|(x, y)| cal.pose().to_world(pose.to_world(DVec3::new(x, y, 0.0))))
            })
            .collect();
        for image in &truth.images {
            let exposure = truth
                .run
                .exposures
                .iter()
                .find(|e| e.id == image.exposure)
                .unwrap();
            if !exposure.phantoms.contains(&cal.id) {
                continue;
            }
            let det = truth
                .run
                .detectors
                .iter()
                .find(|d| d.id == image.detector)
                .unwrap();
            let source = truth
                .run
                .sources
                .iter()
                .find(|s| s.id == det.source)
                .unwrap()
                .position_mm;
            let frame = det.frame();
            let stem = format!("{}-{}", image.exposure, image.detector);
            let (w, h, pixels) = read_image(&dir, &stem).unwrap();
            let img = density(
                &pixels,
                w as usize,
                Reading::of(&setup.scenario.imaging, det.i_max()),
            );
            let s_local = frame.pose.to_local(source);
            let radius_of = |p: DVec3, d_mm: f64| {
                let z = frame.pose.to_local(p).z;
                d_mm / 2.0 * s_local.z / (s_local.z - z) / frame.pixel_pitch_mm[0]
            };
            let radii: Vec<f64> = cal
                .markers
                .iter()
                .map(|m| radius_of(m.position_mm, m.diameter_mm))
                .collect();
            let radius = radii.iter().sum::<f64>() / radii.len().max(1) as f64;
            let min_area = (METAL_BEAD_AREAS * std::f64::consts::PI * radius * radius).max(50.0);
            let metal = metal_mask(&img, min_area as usize);
            let found = find_beads(&img, radius, &metal);
            let all_beads: Vec<DVec2> = image
                .markers
                .iter()
                .map(|m| DVec2::from_array(m.pixel))
                .collect();
            let outlines: Vec<Vec<(DVec2, DVec2)>> = plates
                .iter()
                .map(|c| {
                    (0..4)
                        .filter_map(|k| {
                            Some((
                                frame.project(source, c[k])?,
                                frame.project(source, c[(k + 1) % 4])?,
                            ))
                        })
                        .collect()
                })
                .collect();
            for m in image
                .markers
                .iter()
                .filter(|m| m.phantom == cal.id && m.inside && m.occluded != Some(true))
            {
                tally.beads += 1;
                let at = DVec2::from_array(m.pixel);
                let best = found
                    .iter()
                    .map(|b| (b.centroid - at).length())
                    .fold(f64::INFINITY, f64::min);
                if best <= 1.0 {
                    tally.found += 1;
                    tally.squared_error_px2 += best * best;
                    if best > 0.25 {
                        tally.misplaced += 1;
                    }
                    continue;
                }
                let window = radius + 4.0;
                let neighbour_px = all_beads
                    .iter()
                    .filter(|&&o| o != at)
                    .map(|&o| (o - at).length())
                    .fold(f64::INFINITY, f64::min);
                if neighbour_px < 4.0 * radius {
                    let near = usize::from(neighbour_px >= 2.5 * radius);
                    tally.overlap[near] += 1;
                    let plate = m.id.split('-').next().unwrap_or("");
                    let edge_on = normals.iter().any(|(id, n)| {
                        id == plate && n.dot(frame.pose.rotation.z_axis).abs() < 0.7
                    });
                    tally.overlap_edge_on[near] += usize::from(edge_on);
                } else if outlines
                    .iter()
                    .flatten()
                    .any(|&(a, b)| to_segment(at, a, b) < window)
                {
                    tally.plate_edge += 1;
                } else if at.x < window
                    || at.y < window
                    || at.x > f64::from(w) - window
                    || at.y > f64::from(h) - window
                {
                    tally.border += 1;
                } else {
                    let seen = probe(&img, radius, &metal, at, 1.5);
                    *tally.other.entry(Cause::of(seen.as_ref())).or_default() += 1;
                    if list {
                        listed.push(list_row(
                            &dir.file_name().unwrap().to_string_lossy(),
                            &image.detector,
                            &m.id,
                            at,
                            neighbour_px,
                            seen.as_ref(),
                        ));
                    }
                }
            }
        }
    }
    println!(
        "Command: `cargo run --release --example missed_beads -- OUT` on an output of {program}\n"
    );
    let causes: Vec<&str> = Cause::ALL.iter().map(|c| c.name()).collect();
    println!(
        "| level | box beads on the images | found | centre error of those found, RMS px | misplaced > 0.25 px | missed: overlap, nearest bead < 2.5 radii (on a plate seen within 45° of edge-on) | overlap, 2.5–4 radii (edge-on) | plate edge | border | other, rejected by: {} |",
        causes.join(" | ")
    );
    println!(
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|{}",
        "---:|".repeat(causes.len())
    );
    for (level, t) in &by_level {
        let other: Vec<String> = Cause::ALL
            .iter()
            .map(|c| t.other.get(c).copied().unwrap_or(0).to_string())
            .collect();
        println!(
            "| {level} | {} | {} | {:.3} | {} | {} ({}) | {} ({}) | {} | {} | {} |",
            t.beads,
            t.found,
            (t.squared_error_px2 / t.found.max(1) as f64).sqrt(),
            t.misplaced,
            t.overlap[0],
            t.overlap_edge_on[0],
            t.overlap[1],
            t.overlap_edge_on[1],
            t.plate_edge,
            t.border,
            other.join(" | ")
        );
    }
    if list {
        println!(
            "\n| run | detector | bead | truth pixel | nearest bead, px | candidate pixel | SNR | response | background | tile noise | verdict |"
        );
        println!("|---|---|---|---|---:|---|---:|---:|---:|---:|---|");
        for row in &listed {
            println!("{row}");
        }
    }
    ExitCode::SUCCESS
}
