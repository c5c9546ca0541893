//! The fixed benchmark scenes, shared by `benches/projector.rs` and `examples/bench_scene.rs`
//! (included with `#[path]`, so this folder is not a bench target of its own).
//!
//! All scenes use run `n2-r07` (noise level 0.45) of `scenarios/biplanar.toml`, detector `det1`
//! (1440², pitch 0.2986 mm, 16 bpp) and its source `tube1`:
//! - calibration: the box's 256 beads (exact spheres);
//! - model: the femoral component (87 372 triangles) and its 6 beads, at the run's pose;
//! - sphere: a UV sphere of 200 × 200 facets (79 600 triangles) at the box origin, sized so that
//!   its shadow covers about 20 % of the image.

#![allow(dead_code)]

use std::path::Path;

use rsasim::geometry::{DVec3, DetectorFrame, Pose, rotation_xyz_deg};
use rsasim::noise::NoiseKey;
use rsasim::phantom::TriMesh;
use rsasim::simulate;
use rsasim::trace::{MeshBvh, Object};

/// Rings × segments of the benchmark sphere: 2·200·199 = 79 600 triangles.
pub const SPHERE_RINGS: u32 = 200;
/// See [`SPHERE_RINGS`].
pub const SPHERE_SEGMENTS: u32 = 200;
/// The share of the image the sphere's shadow is sized to cover.
pub const SPHERE_TARGET_FRACTION: f64 = 0.20;

/// One mesh placed in the world: its local mesh, its BVH and its pose.
pub struct PlacedMesh {
    /// The mesh in its local frame, mm.
    pub mesh: TriMesh,
    /// The BVH over `mesh`.
    pub bvh: MeshBvh,
    /// Local → world (box frame).
    pub pose: Pose,
}

impl PlacedMesh {
    fn new(mesh: TriMesh, pose: Pose) -> PlacedMesh {
        let bvh = MeshBvh::new(&mesh);
        PlacedMesh { mesh, bvh, pose }
    }

    /// The mesh's triangles in world coordinates (mm), as rsasim stores vertices (f32).
    pub fn world_mesh(&self) -> TriMesh {
        TriMesh {
            vertices: self
                .mesh
                .vertices
                .iter()
                .map(|v| {
                    let w = self.pose.to_world(DVec3::from_array(v.map(f64::from)));
                    [w.x as f32, w.y as f32, w.z as f32]
                })
                .collect(),
            triangles: self.mesh.triangles.clone(),
        }
    }

    /// The mesh as one traced object.
    pub fn object(&self) -> Object<'_> {
        Object::Mesh {
            bvh: &self.bvh,
            pose: self.pose,
        }
    }
}

/// Everything the benchmarks and the peer export need.
pub struct Scenes {
    /// The detector `det1` of run `n2-r07`.
    pub frame: DetectorFrame,
    /// Its source `tube1`, mm.
    pub source: DVec3,
    /// I_max = 65535 (16 bpp).
    pub i_max: u16,
    /// The run's noise level (0.45).
    pub noise_level: f64,
    /// Scenario seed, level index and run index, for the noise keys.
    pub seed: u64,
    /// Noise level index of the run.
    pub level_index: u32,
    /// Run index within its level.
    pub run_index: u32,
    /// Box beads: centre and radius, mm, world.
    pub box_beads: Vec<(DVec3, f64)>,
    /// Femoral component beads: centre and radius, mm, world.
    pub femur_beads: Vec<(DVec3, f64)>,
    /// The femoral component at the run's pose.
    pub femur: PlacedMesh,
    /// The benchmark sphere.
    pub sphere: PlacedMesh,
    /// The sphere's radius, mm.
    pub sphere_radius_mm: f64,
}

fn spheres(beads: &[(DVec3, f64)]) -> Vec<Object<'static>> {
    beads
        .iter()
        .map(|&(centre_mm, radius_mm)| Object::Sphere {
            centre_mm,
            radius_mm,
        })
        .collect()
}

impl Scenes {
    /// Builds the scenes from `scenarios/biplanar.toml` (relative to the crate root).
    pub fn load() -> Scenes {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/biplanar.toml");
        let plan = simulate::prepare(&path).expect("biplanar.toml is valid");
        let s = &plan.loaded.scenario;
        let run = plan
            .runs
            .iter()
            .find(|r| r.id == "n2-r07")
            .expect("run n2-r07");
        let det = &run.detectors[0];
        let frame = det.frame();
        let source = run.source_of(det);
        let index = |id: &str| plan.models.iter().position(|m| m.id == id).unwrap();
        let beads = |i: usize| -> Vec<(DVec3, f64)> {
            run.phantoms[i]
                .markers
                .iter()
                .map(|m| (m.position_mm, m.diameter_mm / 2.0))
                .collect()
        };
        let (box_i, femur_i) = (index("box"), index("femur"));
        let femur_mesh = plan.models[femur_i].mesh.as_ref().unwrap().as_ref().clone();
        let femur = PlacedMesh::new(femur_mesh, run.phantoms[femur_i].pose());

        // Sphere at the box origin; its shadow radius on the detector plane is
        // D·tan(asin(r/d)) (d: source–centre, D: source–plane distance).
        let centre = DVec3::ZERO;
        let normal = frame.pose.rotation.col(2);
        let plane_distance = (source - frame.pose.position_mm).dot(normal);
        let [w, h] = frame.size_mm();
        let shadow_radius = (SPHERE_TARGET_FRACTION * w * h / std::f64::consts::PI).sqrt();
        let sphere_radius_mm =
            (source - centre).length() * (shadow_radius / plane_distance).atan().sin();
        let sphere = PlacedMesh::new(
            TriMesh::uv_sphere(sphere_radius_mm, SPHERE_RINGS, SPHERE_SEGMENTS),
            Pose {
                position_mm: centre,
                rotation: rotation_xyz_deg([10.0, 20.0, 30.0]),
            },
        );
        Scenes {
            frame,
            source,
            i_max: det.i_max(),
            noise_level: run.noise_level,
            seed: s.seed,
            level_index: run.noise_level_index,
            run_index: run.run_index,
            box_beads: beads(box_i),
            femur_beads: beads(femur_i),
            femur,
            sphere,
            sphere_radius_mm,
        }
    }

    /// The calibration exposure: the box's beads.
    pub fn calibration(&self) -> Vec<Object<'_>> {
        spheres(&self.box_beads)
    }

    /// The model exposure: the femoral component and its beads (what the protocol traces).
    pub fn model(&self) -> Vec<Object<'_>> {
        let mut objects = spheres(&self.femur_beads);
        objects.push(self.femur.object());
        objects
    }

    /// The femoral component alone (the peers' scene: triangles only).
    pub fn femur_mesh(&self) -> Vec<Object<'_>> {
        vec![self.femur.object()]
    }

    /// The benchmark sphere alone.
    pub fn sphere(&self) -> Vec<Object<'_>> {
        vec![self.sphere.object()]
    }

    /// The noise key of an exposure of this run on `det1`.
    pub fn noise_key(&self, exposure: &str) -> NoiseKey {
        NoiseKey::derive(
            self.seed,
            self.level_index,
            self.run_index,
            exposure,
            "det1",
        )
    }

    /// Image width in pixels.
    pub fn width(&self) -> usize {
        self.frame.pixels[0] as usize
    }
}

/// Share of an image's pixels that are non-zero.
pub fn covered_fraction(image: &[u16]) -> f64 {
    image.iter().filter(|&&p| p != 0).count() as f64 / image.len() as f64
}
