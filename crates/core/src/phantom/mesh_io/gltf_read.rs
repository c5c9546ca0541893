//! glTF 2.0 input (`.glb`, `.gltf`). The `gltf` crate parses and validates the JSON; every
//! accessor is then checked here (types, stride, offsets, counts, ranges of its bufferView and
//! buffer) and read by hand, because the crate's readers panic on inconsistent files. Buffers
//! and images named by URI are read through the [`Confinement`] rule.
//!
//! Supported: triangle lists (primitive mode 4, the default) with float VEC3 positions and
//! optional unsigned byte/short/int SCALAR indices; node hierarchies (matrix or TRS) up to
//! [`MAX_NODE_DEPTH`] deep, each node reached once. Refused with a message: other primitive
//! modes, sparse or compressed accessors, quantised positions, inconsistent layouts.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::{DMat4, DVec3};

use super::repack::{self, ImageBytes};
use super::{MAX_TRIANGLES, VertexCheck};
use crate::phantom::TriMesh;
use crate::phantom::confine::{Confinement, MAX_INPUT_BYTES, shorten};

/// Deepest node hierarchy that is followed; deeper (or cyclic) hierarchies are refused.
pub const MAX_NODE_DEPTH: usize = 256;

/// A glTF file read: its mesh in mm and, when it references files, the exact repack of it as
/// one self-contained `.glb` (`None`: the file's own bytes already stand alone).
pub(super) struct GltfMesh {
    pub mesh: TriMesh,
    pub repacked_glb: Option<Vec<u8>>,
}

/// Reads a `.glb` or `.gltf` file's bytes; URIs resolve against `base_dir` under `confine`.
pub(super) fn read_gltf(
    bytes: &[u8],
    base_dir: &Path,
    confine: &Confinement,
    check: &VertexCheck,
) -> Result<GltfMesh, String> {
    check_glb_header(bytes)?;
    check_position_accessors(bytes)?;
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| describe_error(&e))?;
    let json: Cow<[u8]> = if bytes.starts_with(b"glTF") {
        gltf::binary::Glb::from_slice(bytes)
            .map_err(|e| describe_error(&e))?
            .json
    } else {
        Cow::Borrowed(bytes)
    };
    let names = MeshNames::from_json(&json);
    let mut external = false;
    let mut buffers = Vec::new();
    for buffer in gltf.document.buffers() {
        let i = buffer.index();
        let declared = buffer.length();
        if declared as u64 > MAX_INPUT_BYTES {
            return Err(format!(
                "buffer {i} declares {declared} bytes, more than the limit of {MAX_INPUT_BYTES} bytes"
            ));
        }
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                format!("buffer {i} refers to the binary chunk, but there is none: store it in a .glb or give the buffer a `uri`")
            })?,
            gltf::buffer::Source::Uri(uri) => {
                external |= !uri.starts_with("data:");
                read_uri(uri, base_dir, confine).map_err(|e| format!("buffer {i}: {e}"))?
            }
        };
        if data.len() < declared {
            return Err(format!(
                "buffer {i} declares {declared} bytes but holds only {}: the file or its .bin is truncated",
                data.len()
            ));
        }
        buffers.push(data);
    }
    let mut images = Vec::new();
    for image in gltf.document.images() {
        let source = match image.source() {
            gltf::image::Source::Uri { uri, mime_type } => {
                external |= !uri.starts_with("data:");
                Some((uri, mime_type))
            }
            gltf::image::Source::View { .. } => None,
        };
        images.push(source);
    }

    let mut mesh = TriMesh {
        vertices: Vec::new(),
        triangles: Vec::new(),
    };
    let mut roots: Vec<gltf::Node> = match gltf.document.default_scene() {
        Some(scene) => scene.nodes().collect(),
        None => gltf.document.scenes().flat_map(|s| s.nodes()).collect(),
    };
    let mut seen_root = vec![false; gltf.document.nodes().len()];
    roots.retain(|n| !std::mem::replace(&mut seen_root[n.index()], true));
    let mut walk = Walk {
        buffers: &buffers,
        names: &names,
        check,
        visited: vec![false; gltf.document.nodes().len()],
        out: &mut mesh,
    };
    for node in roots {
        walk.node(&node, DMat4::IDENTITY, 0)?;
    }

    let repacked_glb = if external {
        let mut image_bytes = Vec::with_capacity(images.len());
        for (i, source) in images.into_iter().enumerate() {
            image_bytes.push(match source {
                Some((uri, mime)) => Some(ImageBytes {
                    bytes: read_uri(uri, base_dir, confine)
                        .map_err(|e| format!("image {i}: {e}"))?,
                    mime_type: repack::mime_type(uri, mime),
                }),
                None => None,
            });
        }
        Some(repack::repack_glb(&json, &buffers, &image_bytes)?)
    } else {
        None
    };
    Ok(GltfMesh { mesh, repacked_glb })
}

/// Refuses a GLB header the `gltf` crate would mis-handle (a declared length below the header).
fn check_glb_header(bytes: &[u8]) -> Result<(), String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let word = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    match (word(4), word(8)) {
        (Some(2), Some(len)) if len >= 20 && len as usize <= bytes.len() => Ok(()),
        (Some(2), Some(len)) => Err(format!(
            "not a valid glTF 2.0 file: the GLB header declares {len} bytes, but the file has {} (and a GLB needs at least 20)",
            bytes.len()
        )),
        (Some(v), _) => Err(format!(
            "not a valid glTF 2.0 file: GLB version {v}, only version 2 is read"
        )),
        _ => Err("not a valid glTF 2.0 file: the GLB header is truncated".into()),
    }
}

/// Every primitive's `POSITION` must name an existing accessor. The `gltf` crate's validation
/// indexes the accessor list with that number unchecked (gltf-json 1.4.1, `mesh.rs`) and panics
/// on one out of range, so it is checked here first, on the raw JSON. JSON the crate will reject
/// anyway is left to its own error.
fn check_position_accessors(bytes: &[u8]) -> Result<(), String> {
    let json: &[u8] = if bytes.starts_with(b"glTF") {
        // The first chunk of a GLB is its JSON: length at 12, type at 16, data from 20.
        let len = bytes
            .get(12..16)
            .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
        match bytes.get(20..20usize.saturating_add(len)) {
            Some(j) => j,
            None => return Ok(()),
        }
    } else {
        bytes
    };
    let Ok(doc) = serde_json::from_slice::<serde_json::Value>(json) else {
        return Ok(());
    };
    let accessors = doc
        .get("accessors")
        .and_then(|a| a.as_array())
        .map_or(0, Vec::len);
    let meshes = doc.get("meshes").and_then(|m| m.as_array());
    for (m, mesh) in meshes.into_iter().flatten().enumerate() {
        let primitives = mesh.get("primitives").and_then(|p| p.as_array());
        for (p, primitive) in primitives.into_iter().flatten().enumerate() {
            let position = primitive.get("attributes").and_then(|a| a.get("POSITION"));
            if let Some(index) = position.and_then(|i| i.as_u64())
                && index >= accessors as u64
            {
                return Err(format!(
                    "primitive {p} of mesh {m}: POSITION names accessor {index}, but the file has {accessors} accessor(s)"
                ));
            }
        }
    }
    Ok(())
}

/// A parse or validation error of the `gltf` crate, without any value from the file.
fn describe_error(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Deserialize(e) => format!(
            "not a valid glTF 2.0 file: the JSON is malformed or has a value of the wrong type ({:?} error at line {}, column {})",
            e.classify(),
            e.line(),
            e.column()
        ),
        gltf::Error::Validation(list) => {
            let shown: Vec<String> = list
                .iter()
                .take(3)
                .map(|(path, err)| format!("{}: {err}", shorten(&path.to_string())))
                .collect();
            let more = list.len().saturating_sub(3);
            format!(
                "not a valid glTF 2.0 file: {}{}",
                shown.join("; "),
                if more > 0 {
                    format!(" (and {more} more)")
                } else {
                    String::new()
                }
            )
        }
        other => format!("not a valid glTF 2.0 file: {}", shorten(&other.to_string())),
    }
}

/// Reads a buffer or image URI: a base64 `data:` URI, or a percent-encoded path relative to the
/// glTF file's folder, read under the confinement rule.
fn read_uri(uri: &str, base_dir: &Path, confine: &Confinement) -> Result<Vec<u8>, String> {
    let shown = shorten(uri);
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
        if (payload.len() as u64 / 4) * 3 > MAX_INPUT_BYTES {
            return Err(format!(
                "the data URI holds more than the limit of {MAX_INPUT_BYTES} bytes"
            ));
        }
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|_| "the data URI's base64 payload is invalid".to_string());
    }
    if uri.contains("://") || uri.starts_with("file:") {
        return Err(format!(
            "URI `{shown}` is remote: only relative file paths and data: URIs are read"
        ));
    }
    let file: PathBuf = base_dir.join(percent_decode(uri));
    confine
        .read(&file, MAX_INPUT_BYTES)
        .map_err(|e| format!("URI `{shown}` (relative to the glTF file): {e}"))
}

/// Decodes `%XX` escapes (URIs in glTF are percent-encoded); malformed escapes are kept verbatim.
fn percent_decode(s: &str) -> PathBuf {
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
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStringExt;
        PathBuf::from(std::ffi::OsString::from_vec(out))
    }
    #[cfg(not(unix))]
    {
        PathBuf::from(String::from_utf8_lossy(&out).into_owned())
    }
}

/// Mesh names for error messages: the `gltf` crate is built without its `names` feature, so they
/// are read from the JSON directly (best effort; a missing name falls back to the index).
struct MeshNames(Vec<Option<String>>);

impl MeshNames {
    fn from_json(json: &[u8]) -> Self {
        let value: Option<serde_json::Value> = serde_json::from_slice(json).ok();
        let names = value
            .as_ref()
            .and_then(|v| v.get("meshes"))
            .and_then(|m| m.as_array())
            .map(|meshes| {
                meshes
                    .iter()
                    .map(|m| m.get("name").and_then(|n| n.as_str()).map(shorten))
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

/// Where an accessor's elements lie in its buffer, checked to fit.
struct Layout {
    buffer: usize,
    start: usize,
    stride: usize,
    count: usize,
}

/// Checks an accessor against its bufferView and buffer and gives where its elements lie.
fn layout(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Layout, String> {
    let i = acc.index();
    if acc.sparse().is_some() {
        return Err(format!(
            "accessor {i} is sparse: sparse accessors are not supported; export without sparse storage"
        ));
    }
    let view = acc.view().ok_or_else(|| {
        format!(
            "accessor {i} has no bufferView (compressed geometry such as Draco is not supported)"
        )
    })?;
    let v = view.index();
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(format!(
            "bufferView {v} declares byteStride {stride}, smaller than the {elem}-byte elements of accessor {i}"
        ));
    }
    let b = view.buffer().index();
    let available = buffers
        .get(b)
        .map_or(0, Vec::len)
        .min(view.buffer().length());
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > available) {
        return Err(format!(
            "bufferView {v} (offset {}, {} bytes) runs beyond the {available} bytes of buffer {b}",
            view.offset(),
            view.length()
        ));
    }
    let count = acc.count();
    if count > 0 {
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|n| n.checked_add(elem))
            .and_then(|n| n.checked_add(acc.offset()));
        if end.is_none_or(|end| end > view.length()) {
            return Err(format!(
                "accessor {i} ({count} elements of {elem} bytes, every {stride} bytes from offset {}) runs beyond the {} bytes of bufferView {v}",
                acc.offset(),
                view.length()
            ));
        }
    }
    Ok(Layout {
        buffer: b,
        start: view.offset() + acc.offset(),
        stride,
        count,
    })
}

/// Describes an accessor's declared type, e.g. `VEC2 of UNSIGNED_BYTE (normalized)`.
fn declared_type(acc: &gltf::Accessor) -> String {
    use gltf::accessor::{DataType, Dimensions};
    let dims = match acc.dimensions() {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    };
    let comp = match acc.data_type() {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    };
    let norm = if acc.normalized() {
        " (normalized)"
    } else {
        ""
    };
    format!("{dims} of {comp}{norm}")
}

/// The walk over the node hierarchy, appending every primitive in mm.
struct Walk<'a> {
    buffers: &'a [Vec<u8>],
    names: &'a MeshNames,
    check: &'a VertexCheck,
    visited: Vec<bool>,
    out: &'a mut TriMesh,
}

impl Walk<'_> {
    /// Appends a node's mesh (transformed by `parent · node`) and recurses into its children.
    fn node(&mut self, node: &gltf::Node, parent: DMat4, depth: usize) -> Result<(), String> {
        let n = node.index();
        if depth > MAX_NODE_DEPTH {
            return Err(format!(
                "node {n} is nested more than {MAX_NODE_DEPTH} levels deep: the node hierarchy must be a finite tree"
            ));
        }
        if std::mem::replace(&mut self.visited[n], true) {
            return Err(format!(
                "node {n} is reached twice (it has two parents, is listed twice or is part of a cycle): the node hierarchy must be a tree"
            ));
        }
        let local = node.transform().matrix().map(|col| col.map(f64::from));
        let world = parent * DMat4::from_cols_array_2d(&local);
        if !world.is_finite() {
            return Err(format!(
                "node {n}'s transform is not finite (a value beyond the range of 32-bit floats?)"
            ));
        }
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                let what = format!(
                    "primitive {} of {} (node {n})",
                    prim.index(),
                    self.names.describe(mesh.index())
                );
                self.primitive(&prim, &world, &what)?;
            }
        }
        for child in node.children() {
            self.node(&child, world, depth + 1)?;
        }
        Ok(())
    }

    fn primitive(
        &mut self,
        prim: &gltf::Primitive,
        world: &DMat4,
        what: &str,
    ) -> Result<(), String> {
        use gltf::accessor::{DataType, Dimensions};
        if prim.mode() != gltf::mesh::Mode::Triangles {
            return Err(format!(
                "{what} uses mode {:?}: only triangle lists (mode 4 TRIANGLES, the default) are supported, not strips, fans, lines or points",
                prim.mode()
            ));
        }
        let pos = prim
            .get(&gltf::Semantic::Positions)
            .ok_or_else(|| format!("{what} has no POSITION attribute"))?;
        let a = pos.index();
        if pos.dimensions() != Dimensions::Vec3
            || pos.data_type() != DataType::F32
            || pos.normalized()
        {
            return Err(format!(
                "POSITION accessor {a} of {what} is declared {}: positions must be VEC3 of FLOAT (quantised positions are not supported)",
                declared_type(&pos)
            ));
        }
        let lay = layout(&pos, self.buffers).map_err(|e| format!("{what}: {e}"))?;
        let data = &self.buffers[lay.buffer];
        let base = self.out.vertices.len();
        let n = lay.count;
        if base + n > 3 * MAX_TRIANGLES {
            return Err(format!(
                "the meshes hold more than {} vertices (counting every node that instances them): decimate the model",
                3 * MAX_TRIANGLES
            ));
        }
        let flip = world.determinant() < 0.0;
        for k in 0..n {
            let at = lay.start + k * lay.stride;
            let f = |c: usize| {
                data.get(at + 4 * c..at + 4 * c + 4).map_or(f64::NAN, |b| {
                    f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                })
            };
            let file = DVec3::new(f(0), f(1), f(2));
            if !file.is_finite() {
                return Err(format!(
                    "vertex {k} of POSITION accessor {a} ({what}) is not a finite number (NaN or infinite): the file is corrupt"
                ));
            }
            let p = world.transform_point3(file);
            let mm = self.check.to_mm(p, &|| {
                format!("vertex {k} of POSITION accessor {a} ({what}, after the node transforms)")
            })?;
            self.out.vertices.push(mm);
        }
        let indices: Vec<u32> = match prim.indices() {
            None => {
                if !n.is_multiple_of(3) {
                    return Err(format!(
                        "{what} has {n} positions and no indices: a triangle list needs a multiple of 3"
                    ));
                }
                (0..n as u32).collect()
            }
            Some(idx) => {
                let i = idx.index();
                let size = match idx.data_type() {
                    DataType::U8 => 1,
                    DataType::U16 => 2,
                    DataType::U32 => 4,
                    _ => 0,
                };
                if size == 0 || idx.dimensions() != Dimensions::Scalar || idx.normalized() {
                    return Err(format!(
                        "index accessor {i} of {what} is declared {}: indices must be SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
                        declared_type(&idx)
                    ));
                }
                let lay = layout(&idx, self.buffers).map_err(|e| format!("{what}: {e}"))?;
                if !lay.count.is_multiple_of(3) {
                    return Err(format!(
                        "{what} has {} indices, not a multiple of 3: a triangle list needs three per triangle",
                        lay.count
                    ));
                }
                let data = &self.buffers[lay.buffer];
                let mut out = Vec::with_capacity(lay.count);
                for k in 0..lay.count {
                    let at = lay.start + k * lay.stride;
                    let value = match data.get(at..at + size) {
                        Some([b]) => u32::from(*b),
                        Some([b0, b1]) => u32::from(u16::from_le_bytes([*b0, *b1])),
                        Some([b0, b1, b2, b3]) => u32::from_le_bytes([*b0, *b1, *b2, *b3]),
                        _ => u32::MAX,
                    };
                    if value as usize >= n {
                        return Err(format!(
                            "index {k} (triangle {}) of accessor {i} ({what}) points beyond its {n} positions",
                            k / 3
                        ));
                    }
                    out.push(value);
                }
                out
            }
        };
        if self.out.triangles.len() + indices.len() / 3 > MAX_TRIANGLES {
            return Err(format!(
                "the meshes hold more than {MAX_TRIANGLES} triangles (counting every node that instances them): decimate the model"
            ));
        }
        let base = base as u32;
        self.out.triangles.extend(indices.chunks_exact(3).map(|t| {
            if flip {
                [base + t[0], base + t[2], base + t[1]]
            } else {
                [base + t[0], base + t[1], base + t[2]]
            }
        }));
        Ok(())
    }
}
