//! A resected distal femur for the femoral component: its outer (cortical) surface and the
//! medullary/cancellous region inside it, generated from code.
//!
//! # Shape
//! Designed in the femoral component's design frame ([`profile`]: x medio-lateral, y proximal
//! with the lowest point of the metal at y = 0, z anterior, mm) and stored in the component's
//! **local frame** (moved by [`femoral_component_and_origin`]), so that a scenario places bone and
//! component with one and the same pose.
//!
//! - **Resected end.** The bone fills the component's five box cuts ([`profile::cut_planes`],
//!   edges between two cuts rounded by 2 mm, the metal's by 1 mm) up to [`GAP_MM`] = 0.1 mm from
//!   the metal, so the two never overlap. Above the metal the anterior cut plane stays the anterior surface up to about 60 mm
//!   above the flange top (flush with the anterior cortex, no notching), and the posterior cut
//!   plane the posterior surface up to about 35 mm above the posterior condyles.
//! - **Cross-sections.** At each height a superellipse centred on x = 0: 66 mm medio-lateral,
//!   boxy (exponent 4) at the condyles (design y ≤ 45), flaring smoothly (cubic smooth step) to
//!   the round diaphysis of 28 mm outer diameter (exponent 2, centred 1 mm behind the component's
//!   centre) at y ≥ 125, i.e. about 70 mm above the flange top.
//! - **Cortex.** 1.2 mm in the metaphysis and epiphysis (up to y = 70), thickening smoothly to
//!   5.0 mm in the diaphysis (y ≥ 140). The cut faces carry a 1.0 mm wall ([`CUT_WALL_MM`]: the
//!   dense bone–implant interface) and the shaft, cut flat and closed [`SHAFT_LENGTH_MM`] =
//!   130 mm above the flange top, a 1.5 mm cap ([`TOP_WALL_MM`]). The cancellous mesh is the
//!   inside of that wall (cancellous bone and the medullary canal as one region).
//! - **Not modelled:** the intercondylar fossa (bone fills the box cuts between the posterior
//!   condyles), the anterior bow and the valgus angle of the shaft, condylar asymmetry.
//!
//! Overall about 66 mm medio-lateral, 45 mm antero-posterior and 175 mm proximal-distal.
//!
//! # Sources
//! Dimensions are typical adult values chosen within published ranges: distal femoral
//! medio-lateral width about 70–85 mm and antero-posterior depth about 60–70 mm with the
//! articular cartilage (Mahfouz M. et al., *Three-dimensional morphology of the knee reveals
//! ethnic differences*, Clin Orthop Relat Res 2012;470:172–185); the bone here is sized to the
//! 68 mm component. Diaphyseal outer diameter about 26–30 mm with a 4–6 mm cortex, and a thin
//! (about 1–1.5 mm) metaphyseal cortex that thickens towards the shaft (He Q-F. et al.,
//! *Radiographic predictors for bone mineral loss: cortical thickness and index of the distal
//! femur*, Bone Joint Res 2018;7:468–475; Huppke C.M. et al., *Cortical bone thickness on
//! preoperative CT scans as predictor of bone quality in distal femur fractures*, Arch Orthop
//! Trauma Surg 2024;144:731–740, measured 8 and 14 cm above the joint). The metaphysis spans
//! about one condylar width above the joint line (the AO/OTA "square" of the distal segment,
//! Meinberg E.G. et al., J Orthop Trauma 2018;32 Suppl 1:S1–S170).
//!
//! # Construction
//! Both solids are implicit functions (the lofted cross-section intersected with the filleted
//! bone box and the top cut, edges rounded) polygonised by
//! [`marching_tetrahedra`](super::isosurface::marching_tetrahedra) on a [`GRID_STEP_MM`] grid: closed, 2-manifold, outward-wound. On the flat cut faces the surface
//! is exact (the function is linear there), so the 0.1 mm gap holds to f32 precision. Only
//! arithmetic, `sqrt` and `libm` are used, nothing random: the meshes are the same bytes on
//! every platform.

use glam::DVec3;

use super::TriMesh;
use super::femoral::profile;
use super::femoral::{Y_TOP_ANT, femoral_component_and_origin};
use super::implicit::{Sampling, Superellipse, blend, polygonise, round_intersection, smoothstep};

/// Gap between the bone's cut faces and the metal of the component, mm.
pub const GAP_MM: f64 = 0.1;
/// Cortical wall between the cancellous region and the cut faces, mm.
pub const CUT_WALL_MM: f64 = 1.0;
/// Cortical cap at the top of the shaft, mm.
pub const TOP_WALL_MM: f64 = 1.5;
/// Length of the shaft above the top of the component's anterior flange, mm.
pub const SHAFT_LENGTH_MM: f64 = 130.0;
/// Grid spacing of the marching tetrahedra along x, y, z, mm.
pub const GRID_STEP_MM: [f64; 3] = [1.6, 2.0, 1.6];

/// Radius that rounds the edges between the lofted surface and the cut faces, mm.
const R_EDGE: f64 = 1.5;
/// Radius that rounds the edge of the flat top, mm.
const R_TOP: f64 = 1.5;
/// Heights (design frame, mm) where the condylar cross-section starts to flare and where the
/// diaphysis begins.
const Y_EPIPHYSIS: f64 = 45.0;
const Y_DIAPHYSIS: f64 = 125.0;
/// Posterior surface: from the condylar to the shaft value between these heights, mm.
const Y_POST_FLARE: [f64; 2] = [40.0, 100.0];
/// Cortex: metaphyseal thickness up to the first height, diaphyseal from the second, mm.
const Y_CORTEX: [f64; 2] = [70.0, 140.0];
const CORTEX_MM: [f64; 2] = [1.2, 5.0];
/// Cross-section at the condyles: half medio-lateral width, anterior and posterior extent (the
/// cuts trim both), superellipse exponent.
const CONDYLES: [f64; 4] = [33.0, 32.0, -30.0, 4.0];
/// Cross-section of the diaphysis: radius 14 mm (28 mm diameter), centred at z = −1.
const DIAPHYSIS: [f64; 4] = [14.0, 13.0, -15.0, 2.0];
/// Fillet radius of the bone's edges between two cuts, mm: larger than the metal's
/// ([`profile::BOX_FILLET`]), so that the gap at those edges exceeds [`GAP_MM`] by more than the
/// polygonisation's chord error.
const CUT_FILLET: f64 = 2.0;
/// Above this height the bone box is extended straight up (it is closed at 120 mm), mm.
const Y_BOX_CLAMP: f64 = 110.0;

/// The distal femur's two nested surfaces, both closed and outward-wound, in the femoral
/// component's local frame (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct DistalFemur {
    /// The outer surface of the bone (periosteum and the cut faces).
    pub cortical: TriMesh,
    /// The cancellous bone and medullary canal, strictly inside `cortical`.
    pub cancellous: TriMesh,
}

/// Builds the distal femur (see the module documentation for shape, frame and sources).
/// Deterministic: every call returns the same meshes.
pub fn distal_femur() -> DistalFemur {
    let (_, origin) = femoral_component_and_origin();
    let shape = Shape {
        bone: profile::bone_box(&profile::outer_contour(), CUT_FILLET),
    };
    DistalFemur {
        cortical: polygonise_bone(|p| shape.cortical(p), origin),
        cancellous: polygonise_bone(|p| shape.cancellous(p), origin),
    }
}

/// Height of the flat top of the shaft, design frame, mm.
fn y_top() -> f64 {
    Y_TOP_ANT + SHAFT_LENGTH_MM
}

/// The periosteal cross-section at height `y` (design frame).
fn outer_section(y: f64) -> Superellipse {
    let s = smoothstep(Y_EPIPHYSIS, Y_DIAPHYSIS, y);
    let s_post = smoothstep(Y_POST_FLARE[0], Y_POST_FLARE[1], y);
    Superellipse::mix(CONDYLES, DIAPHYSIS, s, s_post)
}

/// The endosteal cross-section: the periosteal one shrunk by the cortex at height `y`.
fn inner_section(y: f64) -> Superellipse {
    outer_section(y).inset(blend(CORTEX_MM, Y_CORTEX, y))
}

/// The implicit functions of the two solids (design frame, negative inside).
struct Shape {
    /// The bone box shrunk by [`CUT_FILLET`].
    bone: profile::Polygon,
}

impl Shape {
    /// Signed distance to the bone box of the cuts with its edges rounded by [`CUT_FILLET`],
    /// extended straight up above [`Y_BOX_CLAMP`].
    fn cuts(&self, p: DVec3) -> f64 {
        self.bone.sdf([p.z, p.y.min(Y_BOX_CLAMP)]) - CUT_FILLET
    }

    /// The outer bone surface: loft ∩ (bone box − gap) ∩ below the top.
    fn cortical(&self, p: DVec3) -> f64 {
        let loft = outer_section(p.y).distance(p.x, p.z);
        let body = round_intersection(loft, self.cuts(p) + GAP_MM, R_EDGE);
        round_intersection(body, p.y - y_top(), R_TOP)
    }

    /// The cancellous region: the endosteal loft ∩ the cut faces and the top moved in by their
    /// walls.
    fn cancellous(&self, p: DVec3) -> f64 {
        let loft = inner_section(p.y).distance(p.x, p.z);
        let body = round_intersection(loft, self.cuts(p) + GAP_MM + CUT_WALL_MM, R_EDGE);
        round_intersection(body, p.y - (y_top() - TOP_WALL_MM), R_TOP)
    }
}

/// Polygonises `{f < 0}` over a grid enclosing the bone and moves it to the local frame
/// (subtracting `origin`).
fn polygonise_bone(f: impl Fn(DVec3) -> f64, origin: DVec3) -> TriMesh {
    let outer = profile::outer_contour();
    let cuts = profile::cut_planes(&outer);
    // Distal cut: −y ≤ c, posterior cut: −z ≤ c.
    let sampling = Sampling {
        lo: DVec3::new(-CONDYLES[0], -cuts[2].1, -cuts[4].1),
        hi: DVec3::new(CONDYLES[0], y_top(), outer.support([1.0, 0.0])),
        step: DVec3::from_array(GRID_STEP_MM),
        offset: DVec3::new(0.17, 0.31, 0.43),
    };
    polygonise(f, &sampling, origin, "distal femur")
}

#[cfg(test)]
mod tests;
