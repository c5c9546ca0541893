//! Exact repacking of a glTF that references files into one self-contained `.glb`: the same
//! JSON document, with every buffer concatenated (each 4-byte aligned) into the GLB's binary
//! chunk and every image named by URI embedded as a bufferView of it. bufferViews keep their
//! indices and point at the same bytes, so accessors, meshes and nodes are untouched: the mesh
//! read back is identical (not re-tessellated), and the output folder stands alone.

use serde_json::{Value, json};

use crate::phantom::confine::MAX_INPUT_BYTES;

/// An image to embed, with its MIME type.
pub(super) struct ImageBytes {
    /// The image file's bytes.
    pub bytes: Vec<u8>,
    /// `image/png`, `image/jpeg`, …
    pub mime_type: String,
}

/// MIME type of an image: the one declared, else from the data URI or the file extension.
pub(super) fn mime_type(uri: &str, declared: Option<&str>) -> String {
    if let Some(m) = declared {
        return m.to_string();
    }
    if let Some(rest) = uri.strip_prefix("data:") {
        return rest
            .split([';', ','])
            .next()
            .filter(|m| !m.is_empty())
            .unwrap_or("application/octet-stream")
            .to_string();
    }
    let ext = uri.rsplit('.').next().unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "png" => "image/png",
        "jpg" | "jpeg" => "image/jpeg",
        "webp" => "image/webp",
        "ktx2" => "image/ktx2",
        _ => "application/octet-stream",
    }
    .to_string()
}

/// The GLB bytes of the document `json` with `buffers` (each at least its declared length) and
/// the URI images of `images` (by image index; `None` for images already in a bufferView)
/// embedded in the binary chunk.
pub(super) fn repack_glb(
    json: &[u8],
    buffers: &[Vec<u8>],
    images: &[Option<ImageBytes>],
) -> Result<Vec<u8>, String> {
    let mut root: Value = serde_json::from_slice(json)
        .map_err(|_| "the glTF JSON cannot be re-read for repacking".to_string())?;
    let mut bin: Vec<u8> = Vec::new();
    let mut starts = Vec::with_capacity(buffers.len());
    let declared: Vec<usize> = (0..buffers.len())
        .map(|i| {
            root["buffers"][i]["byteLength"]
                .as_u64()
                .map_or(buffers[i].len(), |n| n as usize)
        })
        .collect();
    for (data, &len) in buffers.iter().zip(&declared) {
        pad4(&mut bin);
        starts.push(bin.len() as u64);
        bin.extend_from_slice(&data[..len.min(data.len())]);
        check_size(bin.len())?;
    }
    let remap = |target: &mut Value| {
        let b = target.get("buffer").and_then(Value::as_u64).unwrap_or(0) as usize;
        let offset = target
            .get("byteOffset")
            .and_then(Value::as_u64)
            .unwrap_or(0);
        let start = starts.get(b).copied().unwrap_or(0);
        if let Some(obj) = target.as_object_mut() {
            obj.insert("buffer".into(), json!(0));
            obj.insert("byteOffset".into(), json!(start + offset));
        }
    };
    let mut views = root["bufferViews"].as_array().cloned().unwrap_or_default();
    for view in &mut views {
        remap(view);
        if let Some(ext) = view.pointer_mut("/extensions/EXT_meshopt_compression") {
            remap(ext);
        }
    }
    for (i, image) in images.iter().enumerate() {
        let Some(image) = image else { continue };
        pad4(&mut bin);
        let offset = bin.len();
        bin.extend_from_slice(&image.bytes);
        check_size(bin.len())?;
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": image.bytes.len()}));
        if let Some(obj) = root["images"][i].as_object_mut() {
            obj.remove("uri");
            obj.insert("bufferView".into(), json!(views.len() - 1));
            obj.insert("mimeType".into(), json!(image.mime_type));
        }
    }
    pad4(&mut bin);
    if let Some(obj) = root.as_object_mut() {
        if !views.is_empty() {
            obj.insert("bufferViews".into(), Value::Array(views));
        }
        obj.insert("buffers".into(), json!([{"byteLength": bin.len()}]));
    }
    let json_bytes = serde_json::to_vec(&root)
        .map_err(|_| "the repacked glTF JSON cannot be written".to_string())?;
    super::assemble_glb(json_bytes, bin)
}

fn pad4(bin: &mut Vec<u8>) {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
}

/// The repacked file must itself be readable under the input limit.
fn check_size(len: usize) -> Result<(), String> {
    if len as u64 > MAX_INPUT_BYTES - (1 << 20) {
        return Err(format!(
            "the buffers and images together exceed the limit of {MAX_INPUT_BYTES} bytes one self-contained .glb may hold"
        ));
    }
    Ok(())
}
