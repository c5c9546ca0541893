//! Reading and writing triangle meshes: glTF 2.0 (`.glb`, `.gltf`) and STL (`.stl`).
//!
//! Everything in the program is in millimetres; files are not. [`load_mesh_in`] takes the size of
//! one file unit in mm (`unit_mm`), and [`default_unit_mm`] gives the customary one: the glTF
//! specification fixes the metre (1000 mm), and STL files from CAD tools are in mm by custom.
//! [`write_glb`] writes metres, as glTF requires, and [`write_stl`] writes mm.
//!
//! Input files are hostile until checked: every file (the mesh, its buffers and images) is read
//! through the [`Confinement`] rule with a size limit, every glTF accessor is checked before it
//! is read, and every vertex must be finite and within ±[`MAX_COORDINATE_MM`] after node
//! transforms and unit scaling. No input reaches a panic; errors name the accessor, node, facet
//! or vertex at fault and never quote the file's contents.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;
use std::sync::Arc;

use glam::DVec3;
use gltf::json;
use json::validation::Checked::Valid;

use super::TriMesh;
use super::confine::{Confinement, MAX_INPUT_BYTES, shown_path};

mod gltf_read;
mod repack;
mod stl_read;

pub use gltf_read::MAX_NODE_DEPTH;

/// Most triangles one mesh may have (after glTF instancing); more are refused.
pub const MAX_TRIANGLES: usize = 10_000_000;

/// Largest |coordinate| of a vertex after unit scaling, mm: a phantom is far smaller, so
/// anything beyond is a wrong `unit_mm` or a corrupt file.
pub const MAX_COORDINATE_MM: f64 = 1e6;

/// Plausible bounding-box diagonal of an RSA phantom, mm: outside it a warning suggests a unit.
pub const PLAUSIBLE_DIAGONAL_MM: (f64, f64) = (1.0, 2000.0);

/// Millimetres per file unit that a file of this kind customarily uses: 1000 for glTF (`.glb`,
/// `.gltf`, whose specification fixes the metre) and 1 for everything else (STL files are in mm
/// by custom).
pub fn default_unit_mm(path: &Path) -> f64 {
    match extension(path).as_str() {
        "glb" | "gltf" => 1000.0,
        _ => 1.0,
    }
}

/// What goes into an output's `phantoms/` for a mesh: bytes that stand alone.
#[derive(Debug, Clone)]
pub struct MeshPackage {
    /// File extension of the packaged file: `glb`, `gltf` or `stl`.
    pub extension: &'static str,
    /// The file's bytes: a byte copy of a `.glb`, self-contained `.gltf` or `.stl`, or the
    /// exact repack of a glTF that references files into one `.glb`.
    pub bytes: Arc<Vec<u8>>,
}

/// A mesh file read and checked.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The triangles in mm, welded (not yet checked for closedness).
    pub mesh: TriMesh,
    /// The self-contained file for an output's `phantoms/`.
    pub package: MeshPackage,
    /// Doubts that do not stop the run (an implausible size for the unit).
    pub warnings: Vec<String>,
}

/// Loads the triangles of a `.glb`, `.gltf` or `.stl` file as one mesh in mm, reading only the
/// file's own folder (see [`load_mesh_in`]); used by tools and tests on trusted files.
pub fn load_mesh(path: &Path, unit_mm: f64) -> Result<TriMesh, String> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let confine = Confinement::new(dir, &[]).map_err(|e| format!("{}: {e}", shown_path(path)))?;
    load_mesh_in(path, unit_mm, &confine).map(|m| m.mesh)
}

/// Loads the triangles of a `.glb`, `.gltf` or `.stl` file as one mesh in mm: file coordinates
/// are multiplied by `unit_mm` (mm per file unit, see [`default_unit_mm`]), and vertices with
/// identical positions are welded so that the mesh can be checked with
/// [`TriMesh::check_closed`]. The file and everything it references are read under `confine`.
///
/// For glTF, the default scene (or, when the file names none, the root nodes of every scene) is
/// walked with each node's transform applied; every primitive must be a triangle list. Buffers
/// may live in the GLB binary chunk, in a file beside the `.gltf` or in a base64 `data:` URI.
/// The error says what is wrong with the file and what would be accepted.
pub fn load_mesh_in(
    path: &Path,
    unit_mm: f64,
    confine: &Confinement,
) -> Result<LoadedMesh, String> {
    if !(unit_mm.is_finite() && unit_mm > 0.0) {
        return Err(format!(
            "unit_mm is {unit_mm}: it must be a positive, finite number of millimetres per file unit"
        ));
    }
    let shown = shown_path(path);
    confine.check(path, MAX_INPUT_BYTES)?;
    let extension: &'static str = match extension(path).as_str() {
        "glb" => "glb",
        "gltf" => "gltf",
        "stl" => "stl",
        "" => {
            return Err(format!(
                "{shown} has no file extension: use .glb, .gltf or .stl"
            ));
        }
        other => {
            return Err(format!(
                "{shown}: unsupported extension `.{}`: use .glb, .gltf or .stl",
                super::confine::shorten(other)
            ));
        }
    };
    let bytes = confine.read(path, MAX_INPUT_BYTES)?;
    let check = VertexCheck { unit_mm };
    let (mut mesh, package) = match extension {
        "stl" => {
            let mesh = stl_read::read_stl(&bytes, &check).map_err(|e| format!("{shown}: {e}"))?;
            (
                mesh,
                MeshPackage {
                    extension,
                    bytes: Arc::new(bytes),
                },
            )
        }
        _ => {
            let dir = path.parent().unwrap_or(Path::new("."));
            let read = gltf_read::read_gltf(&bytes, dir, confine, &check)
                .map_err(|e| format!("{shown}: {e}"))?;
            let package = match read.repacked_glb {
                Some(glb) => MeshPackage {
                    extension: "glb",
                    bytes: Arc::new(glb),
                },
                None => MeshPackage {
                    extension,
                    bytes: Arc::new(bytes),
                },
            };
            (read.mesh, package)
        }
    };
    if mesh.triangles.is_empty() {
        return Err(format!(
            "{shown} contains no triangles: a phantom mesh needs a closed triangle surface"
        ));
    }
    mesh.weld();
    let warnings = unit_warning(&mesh, unit_mm).into_iter().collect();
    Ok(LoadedMesh {
        mesh,
        package,
        warnings,
    })
}

/// Scales file coordinates to mm and refuses what no phantom can be.
pub(crate) struct VertexCheck {
    unit_mm: f64,
}

impl VertexCheck {
    /// `p` (file units, after node transforms) in mm as f32; the error names the vertex (`what`)
    /// and the likely cause: a corrupt value or a wrong `unit_mm`.
    fn to_mm(&self, p: DVec3, what: &dyn Fn() -> String) -> Result<[f32; 3], String> {
        if !p.is_finite() {
            return Err(format!(
                "{} is not a finite number (NaN or infinite): the file is corrupt",
                what()
            ));
        }
        let q = p * self.unit_mm;
        let far = q.abs().max_element();
        if far > MAX_COORDINATE_MM {
            let cause = if p.abs().max_element() * 1000.0 <= MAX_COORDINATE_MM {
                format!(
                    "unit_mm = {} is too large for this file (1 for mm, 10 for cm, 25.4 for inches, 1000 for metres)",
                    number(self.unit_mm)
                )
            } else {
                "the vertex (or a node transform) is far beyond any phantom: the file is corrupt or in the wrong unit".into()
            };
            return Err(format!(
                "{} lies {far:.3e} mm from the origin after scaling by unit_mm = {}, beyond ±{MAX_COORDINATE_MM:e} mm: {cause}",
                what(),
                number(self.unit_mm)
            ));
        }
        Ok([q.x as f32, q.y as f32, q.z as f32])
    }
}

/// A warning when the mesh's bounding-box diagonal is implausible for an RSA phantom, with the
/// `unit_mm` that would give it a plausible size.
fn unit_warning(mesh: &TriMesh, unit_mm: f64) -> Option<String> {
    let (lo, hi) = mesh.bounds_mm();
    let diagonal = (hi - lo).length();
    let (min, max) = PLAUSIBLE_DIAGONAL_MM;
    if (min..=max).contains(&diagonal) {
        return None;
    }
    let file_units = diagonal / unit_mm;
    let suggestion = [
        (1.0, "mm"),
        (10.0, "cm"),
        (25.4, "inches"),
        (1000.0, "metres"),
    ]
    .into_iter()
    .filter(|(u, _)| (min..=max).contains(&(file_units * u)))
    .min_by(|a, b| {
        let score = |u: f64| (file_units * u / 100.0).ln().abs();
        score(a.0).total_cmp(&score(b.0))
    });
    let hint = match suggestion {
        Some((u, name)) => format!("if the file is in {name}, set unit_mm = {u}"),
        None => "check the file's unit and set unit_mm (1 for mm, 10 for cm, 25.4 for inches, 1000 for metres)".into(),
    };
    Some(format!(
        "the mesh's bounding box is {diagonal:.3e} mm across with unit_mm = {}, implausible for an RSA phantom ({min} mm to {max} mm): {hint}",
        number(unit_mm)
    ))
}

/// A number for a message: plain when moderate, in exponent form when huge or tiny.
fn number(x: f64) -> String {
    if x != 0.0 && !(1e-3..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Lower-case file extension without the dot, or "" when there is none.
fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// The binary glTF 2.0 bytes of `mesh`: positions in metres (mm / 1000, as glTF requires) as
/// float VEC3 with min/max, indices as u32, one mesh, one node, one scene. The same mesh always
/// gives the same bytes.
pub fn glb_bytes(mesh: &TriMesh) -> Result<Vec<u8>, String> {
    let positions: Vec<[f32; 3]> = mesh
        .vertices
        .iter()
        .map(|v| v.map(|c| (f64::from(c) / 1000.0) as f32))
        .collect();
    let mut bin = Vec::with_capacity(positions.len() * 12 + mesh.triangles.len() * 12);
    for p in &positions {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let positions_len = bin.len();
    for t in &mesh.triangles {
        for i in t {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if positions.is_empty() {
        return Err("the mesh has no vertices: there is nothing to write".into());
    }

    let mut root = json::Root {
        asset: json::Asset {
            generator: Some("rsasim".into()),
            ..Default::default()
        },
        ..Default::default()
    };
    let buffer = root.push(json::Buffer {
        byte_length: json::validation::USize64::from(bin.len()),
        uri: None,
        extensions: Default::default(),
        extras: Default::default(),
    });
    let view = |root: &mut json::Root, offset: usize, length: usize, target| {
        root.push(json::buffer::View {
            buffer,
            byte_length: json::validation::USize64::from(length),
            byte_offset: Some(json::validation::USize64::from(offset)),
            byte_stride: None,
            target: Some(Valid(target)),
            extensions: Default::default(),
            extras: Default::default(),
        })
    };
    let pos_view = view(
        &mut root,
        0,
        positions_len,
        json::buffer::Target::ArrayBuffer,
    );
    let idx_view = view(
        &mut root,
        positions_len,
        bin.len() - positions_len,
        json::buffer::Target::ElementArrayBuffer,
    );
    let accessor = |root: &mut json::Root,
                    view,
                    count: usize,
                    ty,
                    kind,
                    min_max: Option<([f32; 3], [f32; 3])>| {
        root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(json::validation::USize64(0)),
            count: json::validation::USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(ty)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(kind),
            min: min_max.map(|(lo, _)| serde_json::json!(lo)),
            max: min_max.map(|(_, hi)| serde_json::json!(hi)),
            normalized: false,
            sparse: None,
        })
    };
    let pos = accessor(
        &mut root,
        pos_view,
        positions.len(),
        json::accessor::ComponentType::F32,
        json::accessor::Type::Vec3,
        Some((lo, hi)),
    );
    let idx = accessor(
        &mut root,
        idx_view,
        mesh.triangles.len() * 3,
        json::accessor::ComponentType::U32,
        json::accessor::Type::Scalar,
        None,
    );
    let gltf_mesh = root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        primitives: vec![json::mesh::Primitive {
            attributes: BTreeMap::from([(Valid(json::mesh::Semantic::Positions), pos)]),
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(idx),
            material: None,
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(gltf_mesh),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        nodes: vec![node],
    });
    root.scene = Some(scene);

    let json_bytes = json::serialize::to_vec(&root)
        .map_err(|e| format!("cannot serialise the glTF JSON: {e}"))?;
    assemble_glb(json_bytes, bin)
}

/// A GLB file (version 2) of a JSON chunk and a binary chunk; both are padded to 4 bytes.
fn assemble_glb(json_bytes: Vec<u8>, bin: Vec<u8>) -> Result<Vec<u8>, String> {
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0,
        },
        json: Cow::Owned(json_bytes),
        bin: Some(Cow::Owned(bin)),
    };
    glb.to_vec()
        .map_err(|e| format!("cannot assemble the GLB: {e}"))
}

/// Writes `mesh` as binary glTF 2.0 (see [`glb_bytes`]) to `writer`.
pub fn write_glb<W: Write>(mesh: &TriMesh, mut writer: W) -> Result<(), String> {
    let bytes = glb_bytes(mesh)?;
    writer
        .write_all(&bytes)
        .map_err(|e| format!("cannot write the GLB: {e}"))
}

/// Writes `mesh` as binary STL in mm, one facet per triangle with its unit normal.
pub fn write_stl<W: Write>(mesh: &TriMesh, mut writer: W) -> Result<(), String> {
    let facets: Vec<stl_io::Triangle> = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
            let [pa, pb, pc] = [a, b, c].map(|v| DVec3::from_array(v.map(f64::from)));
            let n = (pb - pa).cross(pc - pa).normalize_or_zero();
            stl_io::Triangle {
                normal: stl_io::Normal::new([n.x as f32, n.y as f32, n.z as f32]),
                vertices: [a, b, c].map(stl_io::Vertex::new),
            }
        })
        .collect();
    stl_io::write_stl(&mut writer, facets.iter()).map_err(|e| format!("cannot write the STL: {e}"))
}

#[cfg(test)]
mod tests;
