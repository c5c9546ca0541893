//! A generic total-knee femoral component with tantalum RSA beads, generated from code.
//!
//! # Shape
//! Two condyles with a J-curved sagittal profile (posterior arc 19 mm, distal arc 38 mm, anterior
//! arc 20 mm; see [`profile`]), an anterior flange that narrows proximally and carries a shallow
//! patellar groove, an intercondylar notch (19 mm wide, U-shaped at its anterior end) between the
//! posterior condyles (each domed with a 35 mm coronal radius), and on the bone side the usual five box cuts (anterior, anterior chamfer,
//! distal, posterior chamfer, posterior) with 7.5–9 mm of metal under them. Outer edges are
//! rounded (3 mm at the medio-lateral sides). The design is symmetric medio-laterally, so it
//! serves as a left or a right component. Overall about 68 mm medio-lateral, 59 mm
//! antero-posterior and 54 mm proximal-distal.
//!
//! The solid is an implicit function (a constructive-solid-geometry combination of the extruded
//! sagittal profile, the side faces, the caps and the notch, with rounded intersections) and its
//! surface comes from [`marching_tetrahedra`] on a [`GRID_STEP_MM`] grid: closed, 2-manifold,
//! outward-wound and free of self-intersections by construction. Only `sqrt`, arithmetic and
//! `libm` are used, and nothing random, so the mesh is the same bytes on every platform.
//!
//! # Local frame
//! Millimetres. The origin is the centre of the mesh's axis-aligned bounding box; **x** is
//! medio-lateral, **y** points proximally along the femoral axis (up, away from the joint), and
//! **z** points anteriorly. (x, y, z) is right-handed; with x pointing to the patient's left the
//! frame suits a right knee, with x to the right a left knee.
//!
//! # Beads
//! Six 1.0 mm tantalum beads K1–K6 sit in the bone bed just proximal to the component, as an RSA
//! lab places femoral markers in the distal metaphysis (here fixed rigidly to the component, as in
//! a phantom where implant and bone are one block): a low ring 7–13 mm above the top of the
//! anterior flange (K1 behind the anterior cortex, K2 central, K3 posterior-medial, 27 mm above
//! the posterior condyles) and a high ring 25 mm above it (K4 anterior-medial, K5 central, K6
//! posterior-lateral). Their surfaces are 10–36 mm from the metal.
//!
//! Why there: a bead on or behind the bone cuts is hidden in both standard views. Seen
//! antero-posteriorly, the anterior flange covers the whole bone box up to its top; seen
//! laterally, the J-shaped profile is 68 mm deep along the beam, so a tilt of ±10° about the
//! femoral or the antero-posterior axis sweeps its shadow by about ±7 mm; beads on posts beyond
//! the sides would need posts about 8 mm long to clear it. Proximal to the flange top both shadows
//! end. Within that region the beads are spread in all three directions (smallest/largest
//! covariance eigenvalue about 0.68), and no two of them line up within 25° of either beam (the
//! x or the z axis), so their blobs stay apart. The tests render both views over rotations of up
//! to ±12° about each local axis and check that every bead's disc is clear of the metal's shadow
//! and of every other bead's disc.

pub mod profile;

use glam::DVec3;

use super::TriMesh;
use super::implicit::{round_intersection, smoothstep};
use super::isosurface::{Grid, marching_tetrahedra, sample};
use profile::{BoneBox, Polygon};

/// Grid spacing of the marching tetrahedra along x (medio-lateral) and in the sagittal y–z plane,
/// mm. The shape is mostly an extrusion along x, so x can be sampled more coarsely.
pub const GRID_STEP_MM: [f64; 2] = [2.0, 0.9];
/// Half the medio-lateral width at the condyles, mm.
pub(crate) const HALF_WIDTH: f64 = 34.0;
/// The flange narrows by this many mm of half-width per mm above [`TAPER_START_Y`].
const FLANGE_TAPER: f64 = 0.35;
/// Height (design frame, mm above the lowest point) where the flange starts to narrow.
const TAPER_START_Y: f64 = 22.0;
/// Top of the anterior flange, mm above the lowest point.
pub(crate) const Y_TOP_ANT: f64 = 54.0;
/// Top of the posterior condyles, mm above the lowest point.
pub(crate) const Y_TOP_POST: f64 = 40.0;
/// Rounding radii, mm: medio-lateral side edges, top caps, bone-side edges, notch edges.
const R_SIDE: f64 = 3.0;
const R_CAP: f64 = 1.5;
const R_INNER: f64 = 1.0;
const R_NOTCH_EDGE: f64 = 1.5;
/// Intercondylar notch half-width, and the z of its anterior end (design frame), mm.
pub(crate) const NOTCH_HALF_WIDTH: f64 = 9.5;
const NOTCH_END_Z: f64 = 2.0;
/// Coronal radius of the condyles' articular surface, mm.
pub(crate) const R_CORONAL: f64 = 35.0;
/// Medio-lateral distance of each condyle's lowest line from the midplane, mm: the middle of the
/// condyle between the notch and the side.
pub(crate) const CONDYLE_CENTRE_X: f64 = 0.5 * (NOTCH_HALF_WIDTH + HALF_WIDTH);
/// Patellar groove depth and half-width, mm.
const GROOVE_DEPTH: f64 = 2.5;
const GROOVE_HALF_WIDTH: f64 = 16.0;
/// Bead diameter, mm.
const BEAD_DIAMETER: f64 = 1.0;
/// Bead centres K1–K6 in the local frame, mm (see the module documentation): a low ring just above
/// the anterior flange and a high ring 25 mm above it, each anterior, central and posterior.
const BEAD_CENTRES_MM: [[f64; 3]; 6] = [
    [6.0, 34.0, 12.0],    // K1: above the flange, behind the anterior cortex
    [0.0, 36.0, 2.0],     // K2: central
    [-14.0, 40.0, -12.0], // K3: above the posterior condyles, medial side
    [-10.0, 52.0, 12.0],  // K4: high, anterior
    [-4.0, 52.0, 6.0],    // K5: high, central
    [14.0, 52.0, -6.0],   // K6: high, posterior, lateral side
];

/// A tantalum marker bead fixed to the component, in the component's local frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FemoralBead {
    /// Marker id, "K1", "K2", …
    pub id: String,
    /// Centre, mm, local frame.
    pub position_mm: [f64; 3],
    /// Diameter, mm.
    pub diameter_mm: f64,
}

/// The femoral component: its closed surface mesh and its beads, both in the local frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FemoralComponent {
    /// Closed, outward-wound surface, mm.
    pub mesh: TriMesh,
    /// Marker beads outside the metal.
    pub beads: Vec<FemoralBead>,
}

/// Builds the femoral component (see the module documentation for shape, frame and beads).
/// Deterministic: every call returns the same mesh and beads.
pub fn femoral_component() -> FemoralComponent {
    femoral_component_and_origin().0
}

/// Builds the femoral component and returns with it the position of its local frame's origin in
/// the design frame of [`profile`] (x as local, lowest point of the metal at y = 0), mm: a point's
/// local coordinates are its design coordinates minus this origin. Models made to fit the
/// component (the distal femur) are designed against [`profile`] and moved by it.
pub fn femoral_component_and_origin() -> (FemoralComponent, DVec3) {
    let outer = profile::outer_contour();
    let bone = BoneBox::new(&outer);
    let (grid, values) = sample_solid(&outer, &bone);
    // The grid encloses the solid with a margin, so the surface always closes.
    let surface = marching_tetrahedra(&grid, &values)
        .unwrap_or_else(|e| panic!("femoral component grid: {e}"));

    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for v in &surface.vertices {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    let centre = (lo + hi) * 0.5;
    let vertices = surface
        .vertices
        .iter()
        .map(|v| (*v - centre).as_vec3().to_array())
        .collect();
    let beads = BEAD_CENTRES_MM
        .iter()
        .enumerate()
        .map(|(i, p)| FemoralBead {
            id: format!("K{}", i + 1),
            position_mm: *p,
            diameter_mm: BEAD_DIAMETER,
        })
        .collect();
    let component = FemoralComponent {
        mesh: TriMesh {
            vertices,
            triangles: surface.triangles,
        },
        beads,
    };
    (component, centre)
}

/// The sampling grid (design frame: lowest point at y = 0) and the implicit function at its nodes.
fn sample_solid(outer: &Polygon, bone: &BoneBox) -> (Grid, Vec<f64>) {
    let h = DVec3::new(GRID_STEP_MM[0], GRID_STEP_MM[1], GRID_STEP_MM[1]);
    let z_min = -outer.support([-1.0, 0.0]);
    let z_max = outer.support([1.0, 0.0]);
    // A fractional offset keeps nodes off the flat faces (no systematic zero values).
    let origin =
        DVec3::new(-HALF_WIDTH, 0.0, z_min) - DVec3::new(2.0 - 0.13, 2.0 - 0.29, 2.0 - 0.41) * h;
    let count = |extent: f64, h: f64| (extent / h).ceil() as usize + 5;
    let n = [
        count(2.0 * HALF_WIDTH, h.x),
        count(Y_TOP_ANT, h.y),
        count(z_max - z_min, h.z),
    ];
    let grid = Grid { origin, step: h, n };
    // The sagittal distances do not depend on x: tabulate them once per (y, z) node.
    let (ny, nz) = (grid.n[1], grid.n[2]);
    let mut tables = Vec::with_capacity(ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            let p = grid.node(0, j, k);
            tables.push((outer.sdf([p.z, p.y]), bone.sdf([p.z, p.y])));
        }
    }
    let mut node = 0usize;
    let values = sample(&grid, |p| {
        let (j, k) = ((node / grid.n[0]) % ny, node / (grid.n[0] * ny));
        node += 1;
        let (s_outer, s_bone) = tables[j + ny * k];
        solid(p, s_outer, s_bone)
    });
    (grid, values)
}

/// How much of the anterior (trochlear) part there is at design `z`: 0 over
/// the condyles, rising smoothly to 1 on the trochlea (from 6 mm behind to 4 mm in front of the
/// notch's anterior end).
fn anterior_weight(z: f64) -> f64 {
    smoothstep(NOTCH_END_Z - 6.0, NOTCH_END_Z + 4.0, z)
}

/// How far the condyles' articular surface rises, mm, above the line of their lowest points
/// (x = ±[`CONDYLE_CENTRE_X`]) at design `x`, `z` for a coronal radius `r_coronal` mm: the
/// parabola `u² / 2r` of the distance `u` from the condyle's centre (clamped to the condyle,
/// between the notch and the side), fading out towards the trochlea. The component uses
/// [`R_CORONAL`]; a tibial insert that conforms to it uses a larger radius.
pub(crate) fn condylar_dome_mm(x: f64, z: f64, r_coronal: f64) -> f64 {
    let u = x.abs().clamp(NOTCH_HALF_WIDTH, HALF_WIDTH) - CONDYLE_CENTRE_X;
    u * u / (2.0 * r_coronal) * (1.0 - anterior_weight(z))
}

/// The implicit function of the component (design frame, negative in the metal), given the
/// sagittal distances to the outer J-contour and to the bone box at (y, z).
fn solid(p: DVec3, s_outer: f64, s_bone: f64) -> f64 {
    // Anterior (trochlear) part: patellar groove; posterior part: condyles domed in the coronal plane.
    let anterior = anterior_weight(p.z);
    let groove = if p.x.abs() < GROOVE_HALF_WIDTH {
        let q = 1.0 - (p.x / GROOVE_HALF_WIDTH).powi(2);
        GROOVE_DEPTH * q * q * anterior
    } else {
        0.0
    };
    let dome = condylar_dome_mm(p.x, p.z, R_CORONAL);
    let half_width =
        HALF_WIDTH - FLANGE_TAPER * (p.y - TAPER_START_Y).max(0.0) * smoothstep(-5.0, 5.0, p.z);
    let sides = p.x.abs() - half_width;
    let cap = p.y - if p.z > 0.0 { Y_TOP_ANT } else { Y_TOP_POST };
    let outer = round_intersection(s_outer + groove + dome, sides, R_SIDE);
    let outer = round_intersection(outer, cap, R_CAP);
    let metal = round_intersection(outer, -s_bone, R_INNER);
    let notch = round_intersection(
        p.x.abs() - NOTCH_HALF_WIDTH,
        p.z - NOTCH_END_Z,
        NOTCH_HALF_WIDTH,
    );
    round_intersection(metal, -notch, R_NOTCH_EDGE)
}

#[cfg(test)]
pub(crate) mod tests;
