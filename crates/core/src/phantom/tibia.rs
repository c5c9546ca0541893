//! A resected proximal tibia for the tibial component: its outer (cortical) surface and the
//! cancellous/medullary region inside it, generated from code, with six tantalum marker beads.
//!
//! # Frame
//! The tibial frame of [`super::tibial`] (x medio-lateral, y proximal along the tibial axis, z
//! anterior, mm; origin at the centre of the baseplate's distal face, the shaft's axis the line
//! x = z = 0), so that a scenario places bone, baseplate and insert with one and the same pose.
//!
//! # Shape
//! - **Resected plateau.** A flat cut perpendicular to the tibial axis at y = −[`GAP_MM`]
//!   (0.1 mm below the baseplate, so the two never overlap), its rim rounded by 1.5 mm. The keel
//!   sits in a cavity [`KEEL_CLEARANCE_MM`] = 1.0 mm wider than the keel on every side (the
//!   room a cement mantle would fill; the cement is not modelled), its rim rounded by 2 mm.
//! - **Cross-sections.** At each height a superellipse centred on the axis: at the cut 74 mm
//!   medio-lateral × 49 mm antero-posterior, boxy (exponent 3), kept down to 10 mm below the cut,
//!   then narrowing smoothly (cubic smooth step) through the metaphysis to the diaphysis, an
//!   ellipse 25 mm medio-lateral × 30 mm antero-posterior, from 75 mm below the cut.
//! - **Cortex.** 1.2 mm in the metaphysis (down to 35 mm below the cut), thickening smoothly to
//!   4.5 mm in the diaphysis (from 95 mm below it). The cut face carries a 1.0 mm wall
//!   ([`CUT_WALL_MM`]: the dense bone–implant interface), the keel's cavity a 1.5 mm one
//!   ([`KEEL_WALL_MM`]: thicker, so that it stays above 0.8 mm after polygonisation where the
//!   fins' rounded corners meet), and the shaft, cut flat and closed [`SHAFT_LENGTH_MM`] = 130 mm
//!   below the resection, a 1.5 mm cap ([`BOTTOM_WALL_MM`]).
//!   The cancellous mesh is the inside of that wall (cancellous bone and the medullary canal as
//!   one region).
//! - **Not modelled:** the fibula, the tibial tuberosity, the posterior slope of the plateau
//!   (the cut is perpendicular to the axis, as in a mechanically aligned knee with the slope in
//!   the insert), the concave posterior outline between the condyles, the triangular section of
//!   the shaft and its offset from the plateau's centre, the cement.
//!
//! Overall about 74 mm medio-lateral, 49 mm antero-posterior and 130 mm proximal-distal.
//!
//! # Markers
//! [`TIBIAL_MARKERS_MM`]: six 1.0 mm tantalum beads T1–T6 in the proximal metaphysis, as an RSA
//! lab places tibial markers around the keel: a high pair 6–9 mm below the cut (T1
//! anterior-medial beyond the medial fin, T2 posterior-lateral beyond the lateral fin), a middle
//! pair 24–30 mm below it under the fins (T3 posterior-medial, T4 anterior-lateral), and a low
//! pair (T5 anterior-medial, 36 mm below the cut, T6 posterior, 46 mm below it and below the
//! stem's tip). They are at least 10 mm apart, more than 3 mm from the cancellous surface and
//! from the keel's cavity, and none lies behind the metal in an antero-posterior or a lateral
//! view (the beam along z or x): each sits more than 1 mm beside the shadow of the stem, the
//! fins and the plate, and no two of them overlap in either view.
//!
//! # Sources
//! Dimensions are typical adult values chosen within published ranges: tibial plateau about
//! 67–83 mm medio-lateral and 43–54 mm antero-posterior in men and women (Cheng F.B. et al.,
//! *Three dimensional morphometry of the knee to design the total knee arthroplasty for Chinese
//! population*, Knee 2009;16:341–347; Hitt K. et al., *Anthropometric measurements of the human
//! knee: correlation to the sizing of current knee arthroplasty systems*, J Bone Joint Surg Am
//! 2003;85-A Suppl 4:115–122), the resection removing about the 10 mm the implant replaces
//! below the joint line. A thin metaphyseal cortex (about 1 mm) thickening to several mm in the
//! diaphysis, whose section narrows from the wide, round metaphysis (Capozza R.F. et al.,
//! *Structural analysis of the human tibia by tomographic (pQCT) serial scans*, J Anat
//! 2010;216:470–481). The metaphysis spans about one plateau width below the joint line (the
//! AO/OTA "square" of the proximal segment, Meinberg E.G. et al., J Orthop Trauma 2018;32
//! Suppl 1:S1–S170).
//!
//! # Construction
//! As the distal femur ([`super::femur`]): both solids are implicit functions (the lofted
//! cross-section intersected with the cut, the bottom and the keel's cavity, edges rounded)
//! polygonised on a [`GRID_STEP_MM`] grid: closed, 2-manifold, outward-wound. On the flat cut face
//! the surface is exact, so the 0.1 mm gap holds to f32 precision. Only arithmetic, `sqrt` and
//! `libm` are used, nothing random: the meshes are the same bytes on every platform.

use glam::DVec3;

use super::TriMesh;
use super::implicit::{Sampling, Superellipse, blend, polygonise, round_intersection, smoothstep};
use super::tibial::{GAP_MM, keel};

/// Room between the keel and the bone of its cavity, on every side, mm.
pub const KEEL_CLEARANCE_MM: f64 = 1.0;
/// Cortical wall between the cancellous region and the cut face, mm.
pub const CUT_WALL_MM: f64 = 1.0;
/// Cortical wall between the cancellous region and the keel's cavity, mm.
pub const KEEL_WALL_MM: f64 = 1.5;
/// Cortical cap at the bottom of the shaft, mm.
pub const BOTTOM_WALL_MM: f64 = 1.5;
/// Length of the bone below the baseplate's distal face, mm.
pub const SHAFT_LENGTH_MM: f64 = 130.0;
/// Grid spacing of the marching tetrahedra along x, y, z, mm.
pub const GRID_STEP_MM: [f64; 3] = [1.6, 2.0, 1.6];
/// Diameter of the marker beads, mm.
pub const MARKER_DIAMETER_MM: f64 = 1.0;
/// The marker beads T1–T6: id and centre in the tibial frame, mm (see the module
/// documentation).
pub const TIBIAL_MARKERS_MM: [(&str, [f64; 3]); 6] = [
    ("T1", [-27.0, -6.0, 10.0]),   // high, anterior-medial, beyond the fin
    ("T2", [26.0, -9.0, -13.0]),   // high, posterior-lateral, beyond the fin
    ("T3", [-13.0, -24.0, -15.0]), // under the medial fin, posterior
    ("T4", [14.0, -30.0, 12.0]),   // under the lateral fin, anterior
    ("T5", [-19.0, -36.0, 10.0]),  // low, anterior-medial
    ("T6", [6.0, -46.0, -12.0]),   // below the stem's tip, posterior
];

/// Radius that rounds the rim of the cut face and of the bottom, mm.
const R_EDGE: f64 = 1.5;
/// Radius that rounds the rim of the keel's cavity, mm.
const R_CAVITY: f64 = 2.0;
/// Heights (tibial frame, mm) where the plateau's cross-section starts to narrow and where the
/// diaphysis begins.
const Y_FLARE: [f64; 2] = [-10.0, -75.0];
/// Cortex: metaphyseal thickness down to the first height, diaphyseal from the second, mm.
const Y_CORTEX: [f64; 2] = [-35.0, -95.0];
const CORTEX_MM: [f64; 2] = [1.2, 4.5];
/// Cross-section at the cut: half medio-lateral width, anterior and posterior extent,
/// superellipse exponent.
const PLATEAU: [f64; 4] = [37.0, 24.5, -24.5, 3.0];
/// Cross-section of the diaphysis: 25 mm medio-lateral, 30 mm antero-posterior, an ellipse.
const DIAPHYSIS: [f64; 4] = [12.5, 15.0, -15.0, 2.0];

/// The proximal tibia's two nested surfaces, both closed and outward-wound, in the tibial
/// frame (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct ProximalTibia {
    /// The outer surface of the bone (periosteum, the cut face and the keel's cavity).
    pub cortical: TriMesh,
    /// The cancellous bone and medullary canal, strictly inside `cortical`.
    pub cancellous: TriMesh,
}

/// Builds the proximal tibia (see the module documentation for shape, frame and sources).
/// Deterministic: every call returns the same meshes.
pub fn proximal_tibia() -> ProximalTibia {
    let [half_width, z_ant, z_post, _] = PLATEAU;
    let sampling = Sampling {
        lo: DVec3::new(-half_width, -SHAFT_LENGTH_MM, z_post),
        hi: DVec3::new(half_width, 0.0, z_ant),
        step: DVec3::from_array(GRID_STEP_MM),
        offset: DVec3::new(0.17, 0.31, 0.43),
    };
    ProximalTibia {
        cortical: polygonise(cortical, &sampling, DVec3::ZERO, "proximal tibia"),
        cancellous: polygonise(cancellous, &sampling, DVec3::ZERO, "proximal tibia"),
    }
}

/// The periosteal cross-section at height `y` (tibial frame).
fn outer_section(y: f64) -> Superellipse {
    let s = smoothstep(Y_FLARE[0], Y_FLARE[1], y);
    Superellipse::mix(PLATEAU, DIAPHYSIS, s, s)
}

/// The endosteal cross-section: the periosteal one shrunk by the cortex at height `y`.
fn inner_section(y: f64) -> Superellipse {
    outer_section(y).inset(blend(CORTEX_MM, Y_CORTEX, y))
}

/// A solid of the bone: `section` lofted, below the cut face moved down by `inset`, above the
/// bottom moved up by `bottom_inset`, outside the keel dilated by `clearance`.
fn bone(p: DVec3, section: Superellipse, inset: f64, bottom_inset: f64, clearance: f64) -> f64 {
    let loft = section.distance(p.x, p.z);
    let body = round_intersection(loft, p.y + inset, R_EDGE);
    let body = round_intersection(body, -SHAFT_LENGTH_MM + bottom_inset - p.y, R_EDGE);
    round_intersection(body, clearance - keel(p), R_CAVITY)
}

/// The outer bone surface (negative inside).
fn cortical(p: DVec3) -> f64 {
    bone(p, outer_section(p.y), GAP_MM, 0.0, KEEL_CLEARANCE_MM)
}

/// The cancellous region: the endosteal loft inside the walls under the cut face, around the
/// keel's cavity and above the bottom (negative inside).
fn cancellous(p: DVec3) -> f64 {
    bone(
        p,
        inner_section(p.y),
        GAP_MM + CUT_WALL_MM,
        BOTTOM_WALL_MM,
        KEEL_CLEARANCE_MM + KEEL_WALL_MM,
    )
}

#[cfg(test)]
mod tests;
