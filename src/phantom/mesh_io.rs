//! Reading and writing triangle meshes: glTF 2.0 (`.glb`, `.gltf`) and STL (`.stl`).
//!
//! Everything in the program is in millimetres; files are not. [`load_mesh`] takes the size of one
//! file unit in mm (`unit_mm`), and [`default_unit_mm`] gives the customary one: the glTF
//! specification fixes the metre (1000 mm), and STL files from CAD tools are in mm by custom.
//! [`write_glb`] writes metres, as glTF requires, and [`write_stl`] writes mm.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::{DMat4, DVec3};
use gltf::json;
use json::validation::Checked::Valid;

use super::TriMesh;

/// Deepest node hierarchy [`load_mesh`] follows; deeper (or cyclic) hierarchies are refused.
const MAX_NODE_DEPTH: usize = 256;

/// Millimetres per file unit that a file of this kind customarily uses: 1000 for glTF (`.glb`,
/// `.gltf`, whose specification fixes the metre) and 1 for everything else (STL files are in mm
/// by custom).
pub fn default_unit_mm(path: &Path) -> f64 {
    match extension(path).as_str() {
        "glb" | "gltf" => 1000.0,
        _ => 1.0,
    }
}

/// Loads the triangles of a `.glb`, `.gltf` or `.stl` file as one mesh in mm: file coordinates are
/// multiplied by `unit_mm` (mm per file unit, see [`default_unit_mm`]), and vertices with identical
/// positions are welded so that the mesh can be checked with [`TriMesh::check_closed`].
///
/// For glTF, the default scene (or, when the file names none, the root nodes of every scene) is
/// walked recursively with each node's transform applied; every primitive must be a triangle list.
/// Buffers may live in the GLB binary chunk, in a file beside the `.gltf` or in a base64 `data:`
/// URI. The error says what is wrong with the file and what would be accepted.
pub fn load_mesh(path: &Path, unit_mm: f64) -> Result<TriMesh, String> {
    if !(unit_mm.is_finite() && unit_mm > 0.0) {
        return Err(format!(
            "unit_mm is {unit_mm}: it must be a positive number of millimetres per file unit"
        ));
    }
    let shown = path.display();
    let mut mesh = match extension(path).as_str() {
        "glb" | "gltf" => load_gltf(path).map_err(|e| format!("{shown}: {e}"))?,
        "stl" => load_stl(path).map_err(|e| format!("{shown}: {e}"))?,
        "" => {
            return Err(format!(
                "{shown} has no file extension: use .glb, .gltf or .stl"
            ));
        }
        other => {
            return Err(format!(
                "{shown}: unsupported extension `.{other}`: use .glb, .gltf or .stl"
            ));
        }
    };
    if mesh.triangles.is_empty() {
        return Err(format!(
            "{shown} contains no triangles: a phantom mesh needs a closed triangle surface"
        ));
    }
    for v in &mut mesh.vertices {
        *v = v.map(|c| (f64::from(c) * unit_mm) as f32);
    }
    mesh.weld();
    Ok(mesh)
}

/// Lower-case file extension without the dot, or "" when there is none.
fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

fn read_file(path: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(path).map_err(|e| format!("cannot read the file: {e}"))
}

fn load_stl(path: &Path) -> Result<TriMesh, String> {
    let mut file = std::fs::File::open(path).map_err(|e| format!("cannot open the file: {e}"))?;
    let stl = stl_io::read_stl(&mut file)
        .map_err(|e| format!("not a readable STL file (binary or ASCII): {e}"))?;
    let vertices: Vec<[f32; 3]> = stl.vertices.iter().map(|v| [v[0], v[1], v[2]]).collect();
    let n = vertices.len();
    let mut triangles = Vec::with_capacity(stl.faces.len());
    for (f, face) in stl.faces.iter().enumerate() {
        if face.vertices.iter().any(|&i| i >= n) {
            return Err(format!(
                "facet {f} refers to a vertex beyond the {n} vertices"
            ));
        }
        triangles.push(face.vertices.map(|i| i as u32));
    }
    Ok(TriMesh {
        vertices,
        triangles,
    })
}

fn load_gltf(path: &Path) -> Result<TriMesh, String> {
    let bytes = read_file(path)?;
    let gltf =
        gltf::Gltf::from_slice(&bytes).map_err(|e| format!("not a valid glTF 2.0 file: {e}"))?;
    let names = MeshNames::from_bytes(&bytes);
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let buffers = resolve_buffers(&gltf, &base_dir)?;

    let roots: Vec<gltf::Node> = match gltf.document.default_scene() {
        Some(scene) => scene.nodes().collect(),
        None => gltf.document.scenes().flat_map(|s| s.nodes()).collect(),
    };
    let mut mesh = TriMesh {
        vertices: Vec::new(),
        triangles: Vec::new(),
    };
    for node in roots {
        add_node(&node, DMat4::IDENTITY, 0, &buffers, &names, &mut mesh)?;
    }
    Ok(mesh)
}

/// Mesh names for error messages: the `gltf` crate is built without its `names` feature, so they
/// are read from the JSON directly (best effort; a missing name falls back to the index).
struct MeshNames(Vec<Option<String>>);

impl MeshNames {
    fn from_bytes(bytes: &[u8]) -> Self {
        let json_bytes: Option<Cow<[u8]>> = if bytes.starts_with(b"glTF") {
            gltf::binary::Glb::from_slice(bytes).ok().map(|g| g.json)
        } else {
            Some(Cow::Borrowed(bytes))
        };
        let value: Option<serde_json::Value> =
            json_bytes.and_then(|j| serde_json::from_slice(&j).ok());
        let names = value
            .as_ref()
            .and_then(|v| v.get("meshes"))
            .and_then(|m| m.as_array())
            .map(|meshes| {
                meshes
                    .iter()
                    .map(|m| m.get("name").and_then(|n| n.as_str()).map(str::to_owned))
                    .collect()
            })
            .unwrap_or_default();
        MeshNames(names)
    }

    fn describe(&self, index: usize) -> String {
        match self.0.get(index) {
            Some(Some(name)) => format!("mesh `{name}`"),
            _ => format!("mesh {index}"),
        }
    }
}

/// The bytes of every buffer, in buffer order, each checked to hold its declared length.
fn resolve_buffers(gltf: &gltf::Gltf, base_dir: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                format!("buffer {i} refers to the binary chunk, but there is none: store it in a .glb or give the buffer a `uri`")
            })?,
            gltf::buffer::Source::Uri(uri) => read_uri(uri, base_dir).map_err(|e| format!("buffer {i}: {e}"))?,
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {i} declares {} bytes but holds only {}: the file or its .bin is truncated",
                buffer.length(),
                data.len()
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Reads a buffer URI: a base64 `data:` URI or a path relative to the `.gltf` file's folder.
fn read_uri(uri: &str, base_dir: &Path) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest
            .split_once(',')
            .ok_or_else(|| "the data URI has no `,` before its payload".to_string())?;
        if !header.ends_with(";base64") {
            return Err(
                "the data URI is not base64-encoded: use `data:application/octet-stream;base64,…`"
                    .into(),
            );
        }
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| format!("the data URI's base64 payload is invalid: {e}"));
    }
    if uri.contains("://") {
        return Err(format!(
            "buffer URI `{uri}` is remote: only relative file paths and data: URIs are read"
        ));
    }
    let file: PathBuf = base_dir.join(percent_decode(uri));
    std::fs::read(&file).map_err(|e| {
        format!(
            "cannot read {} (the buffer URI, relative to the .gltf): {e}",
            file.display()
        )
    })
}

/// Decodes `%XX` escapes (URIs in glTF are percent-encoded); malformed escapes are kept verbatim.
fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%'
            && i + 2 < bytes.len()
            && let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2]))
        {
            out.push((h * 16 + l) as u8);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Appends a node's mesh (transformed by `parent · node`) and recurses into its children.
fn add_node(
    node: &gltf::Node,
    parent: DMat4,
    depth: usize,
    buffers: &[Vec<u8>],
    names: &MeshNames,
    out: &mut TriMesh,
) -> Result<(), String> {
    if depth > MAX_NODE_DEPTH {
        return Err(format!(
            "node {} is nested more than {MAX_NODE_DEPTH} levels deep: the node hierarchy must be a finite tree",
            node.index()
        ));
    }
    let local = node.transform().matrix().map(|col| col.map(f64::from));
    let world = parent * DMat4::from_cols_array_2d(&local);
    if let Some(mesh) = node.mesh() {
        let flip = world.determinant() < 0.0;
        for prim in mesh.primitives() {
            let what = || {
                format!(
                    "primitive {} of {}",
                    prim.index(),
                    names.describe(mesh.index())
                )
            };
            if prim.mode() != gltf::mesh::Mode::Triangles {
                return Err(format!(
                    "{} uses mode {:?}; only triangle meshes can be traced",
                    what(),
                    prim.mode()
                ));
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let positions: Vec<[f32; 3]> = reader
                .read_positions()
                .ok_or_else(|| {
                    format!(
                        "{} has no readable POSITION attribute: it needs float VEC3 positions",
                        what()
                    )
                })?
                .collect();
            let n = positions.len() as u32;
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None if prim.indices().is_some() => {
                    return Err(format!(
                        "{} has indices that cannot be read from its buffer",
                        what()
                    ));
                }
                None => (0..n).collect(),
            };
            if !indices.len().is_multiple_of(3) {
                return Err(format!(
                    "{} has {} indices, not a multiple of 3: a triangle list needs three per triangle",
                    what(),
                    indices.len()
                ));
            }
            if let Some(&bad) = indices.iter().find(|&&i| i >= n) {
                return Err(format!(
                    "{} uses vertex index {bad} but has only {n} positions",
                    what()
                ));
            }
            let base = out.vertices.len() as u32;
            out.vertices.extend(positions.iter().map(|p| {
                let q = world.transform_point3(DVec3::new(p[0].into(), p[1].into(), p[2].into()));
                [q.x as f32, q.y as f32, q.z as f32]
            }));
            out.triangles.extend(indices.chunks_exact(3).map(|t| {
                if flip {
                    [base + t[0], base + t[2], base + t[1]]
                } else {
                    [base + t[0], base + t[1], base + t[2]]
                }
            }));
        }
    }
    for child in node.children() {
        add_node(&child, world, depth + 1, buffers, names, out)?;
    }
    Ok(())
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
