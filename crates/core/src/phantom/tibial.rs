//! A generic total-knee tibial component, generated from code: a titanium-alloy baseplate (tray)
//! with a central stem and two keel fins, and a polyethylene insert on it whose articular
//! surface takes the femoral component's condyles ([`super::femoral`]).
//!
//! # Tibial frame
//! Millimetres, shared by the tray, the insert and the proximal tibia ([`super::tibia`]), so that
//! a scenario places them with one and the same pose. **x** is medio-lateral, **y** points
//! proximally along the tibial (mechanical) axis, **z** anteriorly, as in the femoral
//! component's frame; (x, y, z) is right-handed (x to the patient's left suits a right knee, as
//! for the femoral component, whose design is symmetric too). The **origin** is the centre of the
//! baseplate's distal (bone-facing) face: y = 0 is the plane of that face, which the tibial
//! resection plane lies [`GAP_MM`] below (the bone's cut face at y = −0.1); the line x = z = 0 is
//! the axis of the stem and of the tibial shaft (the centre of every cross-section of the bone).
//! The resection is perpendicular to that axis (no posterior slope).
//!
//! For a knee joint coordinate system (Grood E.S., Suntay W.J., *A joint coordinate system for
//! the clinical description of three-dimensional motions: application to the knee*, J Biomech
//! Eng 1983;105:136–144) the femoral component's x axis serves as the flexion axis and this
//! frame's y axis as the tibial (internal–external rotation) axis; at full extension (below) the
//! two frames are parallel, so flexion, varus–valgus and rotation are all zero there.
//!
//! # Shape
//! - **Baseplate.** Ti-6Al-4V (ASTM F136, material `ti6al4v`): titanium alloy rather than CoCr
//!   because many tibial trays are made of it (its lower stiffness shields the proximal tibia
//!   less), and because in a radiograph it then differs from the CoCr femoral component and
//!   shadows the tibial markers less. A plate [`PLATE_THICKNESS_MM`] = 4 mm thick whose outline
//!   is a rounded rectangle 70 mm medio-lateral × 46 mm antero-posterior with 16 mm corner radii
//!   ([`PLATE_HALF_SIZE_MM`], [`PLATE_CORNER_RADIUS_MM`]), its edges sharp (a radiograph does not
//!   see the half-millimetre chamfers of a real tray). No locking rim for the insert.
//! - **Keel.** A central stem of [`STEM_DIAMETER_MM`] = 14 mm, [`STEM_LENGTH_MM`] = 40 mm below
//!   the plate with a hemispherical tip, and two fins 4 mm thick in the coronal plane reaching to
//!   x = ±20 mm, 10 mm deep at their ends and 28 mm where they meet the stem (their edges
//!   half-round, filleted into the stem by 2 mm). The keel meets the plate's distal face in a sharp
//!   edge.
//! - **Insert.** Ultra-high-molecular-weight polyethylene (material `uhmwpe`, density 0.94
//!   g/cm³, nearly radiolucent but part of a real exam: it is modelled, as a separate mesh, so an
//!   attenuation-mode image has its faint shadow and the femoral component stands on something).
//!   The plate's outline, from [`GAP_MM`] above the plate's top to the articular surface, its top
//!   edges rounded by 1.5 mm. Two dishes, one under each femoral condyle, whose lowest points lie
//!   at x = ±21.75 mm ([`super::femoral`]'s condyle centres), z = 0, [`INSERT_MIN_THICKNESS_MM`]
//!   = 8 mm above the insert's underside (y = [`Y_ARTICULAR_MM`] = 12.1 mm). Each dish rises
//!   sagittally as `z² / 2R` with R = [`R_INSERT_SAGITTAL_MM`] = 80 mm (less conforming than the
//!   condyles' 38 mm distal radius, so the femur can roll and slide on it) and coronally as the
//!   condyles' dome with a radius of [`R_INSERT_CORONAL_MM`] = 40 mm instead of their 35 mm
//!   (flattening anteriorly as theirs does). Between the dishes the surface stays at the height it
//!   has at the notch's edge (a low eminence); the insert is 8 to 12.8 mm thick.
//!
//! Overall the tray is 70 × 44 × 46 mm (x × y × z), the insert 70 × 12.8 × 46 mm.
//!
//! # Full extension
//! With both frames aligned (no rotation) and the tibial origin at
//! [`full_extension_position_mm`] in the femoral component's local frame, the knee is at full
//! extension: the tibial and the femoral long axes are parallel (the component is implanted
//! perpendicular to the mechanical axis, so there is no valgus between them), and the lowest
//! points of the condyles (design x = ±21.75, y = 0, z = −1 mm, the bottom of the distal arc
//! [`super::femoral::profile::C_DIST`]) stand [`CONTACT_GAP_MM`] = 0.1 mm above the lowest points
//! of the insert's dishes. That is the contact assumption: the condyles rest in the dishes'
//! bottoms, both compartments loaded, with a tenth of a millimetre left between the surfaces so
//! that the meshes never overlap. Because the dishes are everywhere less curved than the condyles
//! (sagittally and coronally), that is where the surfaces come closest.
//!
//! # Sources
//! Baseplate thickness, stem and keel are generic values of contemporary modular cemented and
//! cementless tibial trays (plate 3–5 mm, stems of 12–16 mm diameter and 30–45 mm length); the
//! tray's size is that of a middle size fitted to the tibia of [`super::tibia`], whose plateau
//! dimensions are cited there (Hitt K. et al., *Anthropometric measurements of the human knee:
//! correlation to the sizing of current knee arthroplasty systems*, J Bone Joint Surg Am
//! 2003;85-A Suppl 4:115–122, compare tibial anatomy with the trays of current systems). The
//! polyethylene is 8 mm thick under the dishes, the minimum recommended to keep contact stresses
//! in the insert down (Bartel D.L., Bicknell V.L., Wright T.M., *The effect of conformity,
//! thickness, and material on stresses in ultra-high molecular weight components for total joint
//! replacement*, J Bone Joint Surg Am 1986;68:1041–1051).
//!
//! # Construction
//! Both solids are implicit functions (the building blocks of `phantom::implicit`) polygonised
//! on [`GRID_STEP_MM`] grids: closed, 2-manifold, outward-wound. The plate's faces are flat and
//! exact, so the gaps to the bone's cut face and to the insert hold to f32 precision. Only
//! arithmetic, `sqrt` and `libm` are used, nothing random: the meshes are the same bytes on every
//! platform.

use glam::DVec3;

use super::TriMesh;
use super::femoral::{CONDYLE_CENTRE_X, condylar_dome_mm, femoral_component_and_origin, profile};
use super::implicit::{Sampling, polygonise, round_intersection};

/// Gap between the bone's cut face and the baseplate, and between the baseplate and the insert,
/// mm.
pub const GAP_MM: f64 = 0.1;
/// Gap between the condyles' lowest points and the insert's dishes at full extension, mm.
pub const CONTACT_GAP_MM: f64 = 0.1;
/// Thickness of the baseplate's plate, mm.
pub const PLATE_THICKNESS_MM: f64 = 4.0;
/// Half the plate's medio-lateral and antero-posterior size (x, z), mm.
pub const PLATE_HALF_SIZE_MM: [f64; 2] = [35.0, 23.0];
/// Radius of the plate outline's four corners, mm.
pub const PLATE_CORNER_RADIUS_MM: f64 = 16.0;
/// Diameter of the stem, mm.
pub const STEM_DIAMETER_MM: f64 = 14.0;
/// Length of the stem below the plate's distal face, tip included, mm.
pub const STEM_LENGTH_MM: f64 = 40.0;
/// Thickness of the insert under the lowest points of its dishes, mm.
pub const INSERT_MIN_THICKNESS_MM: f64 = 8.0;
/// Height of the dishes' lowest points in the tibial frame, mm.
pub const Y_ARTICULAR_MM: f64 = PLATE_THICKNESS_MM + GAP_MM + INSERT_MIN_THICKNESS_MM;
/// Medio-lateral position of the dishes' lowest points (±), tibial frame, mm: under the
/// femoral condyles' lowest lines.
pub const DISH_CENTRE_X_MM: f64 = CONDYLE_CENTRE_X;
/// Sagittal radius of the insert's dishes, mm.
pub const R_INSERT_SAGITTAL_MM: f64 = 80.0;
/// Coronal radius of the insert's dishes, mm.
pub const R_INSERT_CORONAL_MM: f64 = 40.0;
/// Grid spacing of the marching tetrahedra along x, y, z, mm (both parts).
pub const GRID_STEP_MM: [f64; 3] = [1.2, 1.0, 1.2];

/// Half-thickness of each keel fin (z), mm.
const FIN_HALF_THICKNESS: f64 = 2.0;
/// How far the fins reach medio-laterally, mm.
const FIN_SPAN: f64 = 20.0;
/// The fins' lower edge runs straight from this point (|x|, y) at the stem to the next at the
/// fin's end, mm.
const FIN_EDGE: [[f64; 2]; 2] = [[7.0, -28.0], [FIN_SPAN, -10.0]];
/// Rounding of the fins' edges (their ends and lower edges are half-round), and fillet between
/// the fins and the stem, mm.
const R_FIN: f64 = FIN_HALF_THICKNESS;
const R_KEEL_FILLET: f64 = 2.0;
/// Rounding of the insert's top edges and bottom edges, mm.
const R_INSERT_TOP: f64 = 1.5;
const R_INSERT_BOTTOM: f64 = 0.5;

/// Signed distance to the plate's outline in the x–z plane (a rounded rectangle; exact, negative
/// inside).
pub(crate) fn plate_outline(x: f64, z: f64) -> f64 {
    let r = PLATE_CORNER_RADIUS_MM;
    let qx = x.abs() - (PLATE_HALF_SIZE_MM[0] - r);
    let qz = z.abs() - (PLATE_HALF_SIZE_MM[1] - r);
    let (ox, oz) = (qx.max(0.0), qz.max(0.0));
    (ox * ox + oz * oz).sqrt() + qx.max(qz).min(0.0) - r
}

/// Signed distance to the keel (stem and fins), mm; the keel reaches 1 mm up into the plate.
pub(crate) fn keel(p: DVec3) -> f64 {
    let r = 0.5 * STEM_DIAMETER_MM;
    let tip = r - STEM_LENGTH_MM;
    let radial = (p.x * p.x + p.z * p.z).sqrt();
    let stem = if p.y < tip {
        (radial * radial + (p.y - tip) * (p.y - tip)).sqrt() - r
    } else {
        radial - r
    };
    let [[x0, y0], [x1, y1]] = FIN_EDGE;
    let (dx, dy) = (x1 - x0, y1 - y0);
    let len = (dx * dx + dy * dy).sqrt();
    // Outward normal of the lower edge: (dy, −dx) / len points down and out.
    let below = ((p.x.abs() - x0) * dy - (p.y - y0) * dx) / len;
    let outline = round_intersection(p.x.abs() - FIN_SPAN, below, R_FIN).max(p.y - 1.0);
    let fin = round_intersection(outline, p.z.abs() - FIN_HALF_THICKNESS, R_FIN);
    // The union of stem and fins with their edges filleted: the complement of the rounded
    // intersection of the complements.
    (-round_intersection(-stem, -fin, R_KEEL_FILLET)).max(p.y - 1.0)
}

/// Signed distance to the baseplate (plate and keel; a sharp union).
fn tray(p: DVec3) -> f64 {
    let slab = (p.y - 0.5 * PLATE_THICKNESS_MM).abs() - 0.5 * PLATE_THICKNESS_MM;
    plate_outline(p.x, p.z).max(slab).min(keel(p))
}

/// Height of the insert's articular surface at (x, z), tibial frame, mm.
pub(crate) fn articular_height(x: f64, z: f64) -> f64 {
    // The femoral design z over this point at full extension: the dishes' lowest points (z = 0)
    // lie under the condyles' (design z = C_DIST[0]).
    let z_femoral = z + profile::C_DIST[0];
    Y_ARTICULAR_MM
        + condylar_dome_mm(x, z_femoral, R_INSERT_CORONAL_MM)
        + z * z / (2.0 * R_INSERT_SAGITTAL_MM)
}

/// Signed distance (approximate along the articular surface) to the insert.
fn insert(p: DVec3) -> f64 {
    let top = p.y - articular_height(p.x, p.z);
    let bottom = PLATE_THICKNESS_MM + GAP_MM - p.y;
    let body = round_intersection(plate_outline(p.x, p.z), top, R_INSERT_TOP);
    round_intersection(body, bottom, R_INSERT_BOTTOM)
}

/// The sampling box of a part of the tibial component between heights `y_lo` and `y_hi`.
fn sampling(y_lo: f64, y_hi: f64) -> Sampling {
    let [hx, hz] = PLATE_HALF_SIZE_MM;
    Sampling {
        lo: DVec3::new(-hx, y_lo, -hz),
        hi: DVec3::new(hx, y_hi, hz),
        step: DVec3::from_array(GRID_STEP_MM),
        offset: DVec3::new(0.23, 0.37, 0.11),
    }
}

/// Builds the tibial baseplate (plate and keel) in the tibial frame (see the module
/// documentation). Deterministic: every call returns the same mesh.
pub fn tibial_tray() -> TriMesh {
    polygonise(
        tray,
        &sampling(-STEM_LENGTH_MM, PLATE_THICKNESS_MM),
        DVec3::ZERO,
        "tibial tray",
    )
}

/// Builds the polyethylene insert in the tibial frame (see the module documentation).
/// Deterministic: every call returns the same mesh.
pub fn tibial_insert() -> TriMesh {
    // The surface is highest at the outline's medio-lateral sides (the dome's clamp) and its
    // anterior or posterior edge.
    let [hx, hz] = PLATE_HALF_SIZE_MM;
    let highest = articular_height(hx, hz).max(articular_height(hx, -hz));
    polygonise(
        insert,
        &sampling(PLATE_THICKNESS_MM, highest),
        DVec3::ZERO,
        "tibial insert",
    )
}

/// The position of the tibial frame's origin in the femoral component's local frame at full
/// extension (no rotation between the frames), mm: the insert's dish bottoms
/// [`CONTACT_GAP_MM`] below the condyles' lowest points (see the module documentation).
pub fn full_extension_position_mm() -> [f64; 3] {
    let (_, origin) = femoral_component_and_origin();
    let design = DVec3::new(0.0, -CONTACT_GAP_MM - Y_ARTICULAR_MM, profile::C_DIST[0]);
    (design - origin).to_array()
}

#[cfg(test)]
mod tests;
