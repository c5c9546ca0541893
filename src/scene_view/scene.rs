//! The scene as drawn by the page: every object of the first run in the scanner frame, the
//! envelope each object sweeps over the runs of the protocol, and the warnings placed at the
//! objects they concern. Plain records, serialised into the page as JSON.

use glam::DVec3;
use serde::Serialize;

use crate::diagnostic::{Diagnostic, Segment};
use crate::expand::{self, Run};
use crate::geometry::Pose;
use crate::phantom::{PhantomModel, VolumeShape};
use crate::scenario::Scenario;

use super::decimate::decimate;

/// Runs of the protocol whose poses make up the envelopes (the first ones, in protocol order).
pub const ENVELOPE_RUNS: usize = 200;

/// Triangles a mesh may keep on the page ([`decimate`]).
pub const MAX_MESH_TRIANGLES: usize = 2500;

/// Points on each end ring of an elliptic cylinder.
const RING_POINTS: usize = 32;

/// A point in the scanner frame, mm, rounded to 0.01 mm (the page's precision).
pub type Point = [f64; 3];

/// Everything the page draws.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Scene {
    /// Scenario name.
    pub name: String,
    /// Id of the run drawn (the protocol's first).
    pub run: String,
    /// Runs whose poses the envelopes cover.
    pub envelope_runs: usize,
    /// Runs of the protocol.
    pub total_runs: usize,
    /// X-ray sources.
    pub sources: Vec<SourceView>,
    /// Detectors.
    pub detectors: Vec<DetectorView>,
    /// Phantoms: box, meshes, beads, cylinders.
    pub phantoms: Vec<PhantomView>,
    /// Warnings of the scenario check, placed where they belong.
    pub warnings: Vec<WarningView>,
}

/// Axis-aligned bounds `[low, high]` of what an object sweeps over the runs.
pub type Envelope = [Point; 2];

/// A source.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SourceView {
    /// Scenario id.
    pub id: String,
    /// Focus position in the first run.
    pub position: Point,
    /// What the focus sweeps over the runs; `None` when it does not move.
    pub envelope: Option<Envelope>,
}

/// A detector.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DetectorView {
    /// Scenario id.
    pub id: String,
    /// Id of its source.
    pub source: String,
    /// Corners of the active area in the first run: pixel (0, 0)'s corner first, then along r,
    /// then the far corner, then along c (a closed outline).
    pub corners: [Point; 4],
    /// What the active area sweeps over the runs; `None` when it does not move.
    pub envelope: Option<Envelope>,
    /// Thumbnails of the first run's images, one per exposure.
    pub images: Vec<ImageView>,
}

/// A thumbnail of one image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageView {
    /// Exposure id.
    pub exposure: String,
    /// `data:image/png;base64,…`.
    pub src: String,
}

/// A phantom.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhantomView {
    /// Scenario id.
    pub id: String,
    /// `beads`, `calibration_box`, `mesh` or `elliptic_cylinder`.
    pub kind: String,
    /// Centre of its bounds in the first run (where its label and warnings stand).
    pub centre: Point,
    /// Beads: centre and radius, mm.
    pub beads: Vec<[f64; 4]>,
    /// Its mesh, decimated for drawing.
    pub mesh: Option<MeshView>,
    /// Cuboid volumes (box plates): 8 corners each, corner k at (±x, ±y, ±z) by the bits of k.
    pub cuboids: Vec<[Point; 8]>,
    /// Elliptic cylinders: the two end rings.
    pub cylinders: Vec<[Vec<Point>; 2]>,
    /// What it sweeps over the runs; `None` when it does not move.
    pub envelope: Option<Envelope>,
}

/// A mesh in the first run's pose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeshView {
    /// Vertex coordinates, x y z one after the other.
    pub vertices: Vec<f64>,
    /// Triangle indices, three by three.
    pub triangles: Vec<u32>,
    /// Triangles of the mesh as simulated.
    pub full_triangles: usize,
}

/// A warning, with the object it concerns.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarningView {
    /// The warning's text (message and help), without the file location.
    pub text: String,
    /// Its key in the scenario, e.g. `phantoms[2].position_mm`.
    pub key: Option<String>,
    /// Where it stands in the scene; `None` for a warning about no one object.
    pub at: Option<Point>,
}

/// Rounds to 0.01 mm.
fn round(p: DVec3) -> Point {
    [p.x, p.y, p.z].map(|x| (x * 100.0).round() / 100.0)
}

/// Growing axis-aligned bounds.
#[derive(Debug, Clone, Copy)]
struct Bounds {
    lo: DVec3,
    hi: DVec3,
}

impl Bounds {
    fn empty() -> Bounds {
        Bounds {
            lo: DVec3::splat(f64::INFINITY),
            hi: DVec3::splat(f64::NEG_INFINITY),
        }
    }

    fn add(&mut self, p: DVec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }

    fn add_sphere(&mut self, p: DVec3, r: f64) {
        self.add(p - DVec3::splat(r));
        self.add(p + DVec3::splat(r));
    }

    fn centre(&self) -> DVec3 {
        if self.lo.is_finite() && self.hi.is_finite() {
            (self.lo + self.hi) / 2.0
        } else {
            DVec3::ZERO
        }
    }

    /// The envelope, when it is larger than `first` (the first run's bounds) by more than
    /// 0.01 mm on some side, i.e. the object moves.
    fn envelope_beyond(&self, first: &Bounds) -> Option<Envelope> {
        let moved = (self.lo - first.lo).abs().max_element() > 0.01
            || (self.hi - first.hi).abs().max_element() > 0.01;
        (moved && self.lo.is_finite() && self.hi.is_finite())
            .then(|| [round(self.lo), round(self.hi)])
    }
}

/// Corners of a detector's active area in the box frame (closed outline order).
fn detector_corners(d: &expand::DetectorState) -> [DVec3; 4] {
    let pose = d.pose();
    let half = [
        d.pixels[0] as f64 * d.pixel_pitch_mm[0] / 2.0,
        d.pixels[1] as f64 * d.pixel_pitch_mm[1] / 2.0,
    ];
    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(a, b)| pose.to_world(DVec3::new(a * half[0], b * half[1], 0.0)))
}

/// Bounds of a phantom in a run, in the scanner frame (`scanner` maps box → scanner).
fn phantom_bounds(model: &PhantomModel, pose: &Pose, scanner: &Pose) -> Bounds {
    let mut b = Bounds::empty();
    for (p, r) in model.extent_points() {
        b.add_sphere(scanner.to_world(pose.to_world(p)), r);
    }
    b
}

/// The scene of `scenario`: the first run drawn, envelopes over the first [`ENVELOPE_RUNS`]
/// runs, `warnings` placed on the objects their key paths name, `thumbnails(detector index)`
/// giving each detector's images.
pub fn build(
    scenario: &Scenario,
    models: &[PhantomModel],
    warnings: &[Diagnostic],
    thumbnails: &dyn Fn(usize) -> Vec<ImageView>,
) -> Scene {
    let mut runs = expand::runs(scenario, models).take(ENVELOPE_RUNS);
    let total_runs = scenario.levels().len() * scenario.protocol.runs_per_level as usize;
    let Some(first) = runs.next() else {
        return Scene {
            name: scenario.name.clone(),
            run: String::new(),
            envelope_runs: 0,
            total_runs,
            sources: Vec::new(),
            detectors: Vec::new(),
            phantoms: Vec::new(),
            warnings: warnings.iter().map(|w| place(w, None)).collect(),
        };
    };
    let per_run = |run: &Run| -> (Vec<Bounds>, Vec<Bounds>, Vec<Bounds>) {
        let scanner = run.box_pose_in_scanner;
        let sources = run
            .sources
            .iter()
            .map(|s| {
                let mut b = Bounds::empty();
                b.add(scanner.to_world(s.position_mm));
                b
            })
            .collect();
        let detectors = run
            .detectors
            .iter()
            .map(|d| {
                let mut b = Bounds::empty();
                detector_corners(d)
                    .into_iter()
                    .for_each(|c| b.add(scanner.to_world(c)));
                b
            })
            .collect();
        let phantoms = models
            .iter()
            .zip(&run.phantoms)
            .map(|(m, p)| phantom_bounds(m, &p.pose(), &scanner))
            .collect();
        (sources, detectors, phantoms)
    };
    let first_bounds = per_run(&first);
    let mut all = first_bounds.clone();
    let mut envelope_runs = 1;
    for run in runs {
        envelope_runs += 1;
        let b = per_run(&run);
        for (acc, new) in [(&mut all.0, b.0), (&mut all.1, b.1), (&mut all.2, b.2)] {
            for (a, n) in acc.iter_mut().zip(new) {
                a.add(n.lo);
                a.add(n.hi);
            }
        }
    }
    let scanner = first.box_pose_in_scanner;
    let sources: Vec<SourceView> = first
        .sources
        .iter()
        .enumerate()
        .map(|(i, s)| SourceView {
            id: s.id.clone(),
            position: round(scanner.to_world(s.position_mm)),
            envelope: all.0[i].envelope_beyond(&first_bounds.0[i]),
        })
        .collect();
    let detectors: Vec<DetectorView> = first
        .detectors
        .iter()
        .enumerate()
        .map(|(i, d)| DetectorView {
            id: d.id.clone(),
            source: d.source.clone(),
            corners: detector_corners(d).map(|c| round(scanner.to_world(c))),
            envelope: all.1[i].envelope_beyond(&first_bounds.1[i]),
            images: thumbnails(i),
        })
        .collect();
    let phantoms: Vec<PhantomView> = models
        .iter()
        .zip(&first.phantoms)
        .enumerate()
        .map(|(i, (m, p))| {
            phantom_view(m, &scanner.compose(&p.pose()), first_bounds.2[i], all.2[i])
        })
        .collect();
    let placed = warnings
        .iter()
        .map(|w| {
            let at = anchor(w, &sources, &detectors, &phantoms);
            place(w, at)
        })
        .collect();
    Scene {
        name: scenario.name.clone(),
        run: first.id.clone(),
        envelope_runs,
        total_runs,
        sources,
        detectors,
        phantoms,
        warnings: placed,
    }
}

/// One phantom in its first-run pose `pose` (phantom → scanner).
fn phantom_view(m: &PhantomModel, pose: &Pose, first: Bounds, all: Bounds) -> PhantomView {
    let mesh = m.mesh.as_ref().map(|mesh| {
        let d = decimate(mesh, MAX_MESH_TRIANGLES);
        MeshView {
            vertices: d
                .vertices
                .iter()
                .flat_map(|v| round(pose.to_world(DVec3::from_array(*v))))
                .collect(),
            triangles: d.triangles.iter().flatten().copied().collect(),
            full_triangles: mesh.triangles.len(),
        }
    });
    let mut cuboids = Vec::new();
    let mut cylinders = Vec::new();
    for v in &m.volumes {
        match &v.shape {
            VolumeShape::Mesh => {}
            VolumeShape::Cuboid { .. } => {
                let c = v.corners();
                if c.len() == 8 {
                    cuboids.push(std::array::from_fn(|k| round(pose.to_world(c[k]))));
                }
            }
            VolumeShape::EllipticCylinder {
                radii_mm,
                half_length_mm,
            } => {
                let ring = |z: f64| -> Vec<Point> {
                    (0..RING_POINTS)
                        .map(|k| {
                            let a = std::f64::consts::TAU * k as f64 / RING_POINTS as f64;
                            let local = DVec3::new(
                                radii_mm[0] * libm::cos(a),
                                radii_mm[1] * libm::sin(a),
                                z,
                            );
                            round(pose.to_world(local))
                        })
                        .collect()
                };
                cylinders.push([ring(-half_length_mm), ring(*half_length_mm)]);
            }
        }
    }
    PhantomView {
        id: m.id.clone(),
        kind: m.kind.to_string(),
        centre: round(first.centre()),
        beads: m
            .markers
            .iter()
            .map(|b| {
                let c = round(pose.to_world(b.position_mm));
                [c[0], c[1], c[2], b.diameter_mm / 2.0]
            })
            .collect(),
        mesh,
        cuboids,
        cylinders,
        envelope: all.envelope_beyond(&first),
    }
}

/// Where a warning stands: at the source, detector or phantom its key path starts with (at the
/// bead, for a key inside a phantom's `beads`), else nowhere.
fn anchor(
    w: &Diagnostic,
    sources: &[SourceView],
    detectors: &[DetectorView],
    phantoms: &[PhantomView],
) -> Option<Point> {
    let path = &w.key_path.as_ref()?.0;
    let (Some(Segment::Key(list)), Some(Segment::Index(i))) = (path.first(), path.get(1)) else {
        return None;
    };
    match list.as_str() {
        "sources" => sources.get(*i).map(|s| s.position),
        "detectors" => detectors.get(*i).map(|d| {
            let c = d.corners;
            [0, 1, 2].map(|k| (c[0][k] + c[1][k] + c[2][k] + c[3][k]) / 4.0)
        }),
        "phantoms" => {
            let p = phantoms.get(*i)?;
            let bead = path
                .iter()
                .skip(2)
                .position(|s| *s == Segment::Key("beads".into()));
            let bead = bead.and_then(|k| match path.get(2 + k + 1) {
                Some(Segment::Index(b)) => p.beads.get(*b).map(|b| [b[0], b[1], b[2]]),
                _ => None,
            });
            Some(bead.unwrap_or(p.centre))
        }
        _ => None,
    }
}

/// A warning's record: message and help, its key, its place.
fn place(w: &Diagnostic, at: Option<Point>) -> WarningView {
    let text = match &w.help {
        Some(h) => format!("{} ({h})", w.message),
        None => w.message.clone(),
    };
    WarningView {
        text,
        key: w.key_path.as_ref().map(ToString::to_string),
        at,
    }
}
