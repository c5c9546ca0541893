//! STL input, binary and ASCII, read by hand so that a hostile file is refused with a precise
//! message: a binary file must be exactly 84 + 50 · (its declared triangle count) bytes, an ASCII
//! file must follow `solid … facet normal … outer loop … vertex ×3 … endloop … endfacet …
//! endsolid`. Messages give facet numbers and line numbers, never the file's text.

use glam::DVec3;

use super::{MAX_TRIANGLES, VertexCheck};
use crate::phantom::TriMesh;

/// Triangles of an STL file as a triangle soup in mm (three vertices per facet, welded later).
pub(super) fn read_stl(bytes: &[u8], check: &VertexCheck) -> Result<TriMesh, String> {
    let declared = bytes
        .get(80..84)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64);
    let binary_len = declared.map(|n| 84 + 50 * n);
    if binary_len == Some(bytes.len() as u64) {
        return read_binary(bytes, check);
    }
    if looks_ascii(bytes) {
        return read_ascii(bytes, check).map_err(|e| match (declared, binary_len) {
            (Some(n), Some(len)) => format!(
                "not a valid ASCII STL ({e}), nor a binary STL (its header declares {n} triangles, {len} bytes, but the file has {} bytes)",
                bytes.len()
            ),
            _ => format!("not a valid ASCII STL: {e}"),
        });
    }
    match (declared, binary_len) {
        (Some(n), Some(len)) => Err(format!(
            "binary STL declares {n} triangles, which take {len} bytes, but the file has {} bytes: it is truncated or not an STL file",
            bytes.len()
        )),
        _ => Err(format!(
            "the file has {} bytes, too short for a binary STL (84-byte header) and not ASCII STL text",
            bytes.len()
        )),
    }
}

/// ASCII STL starts with `solid` (after blanks) and has no NUL byte in its first kilobyte.
fn looks_ascii(bytes: &[u8]) -> bool {
    let head = &bytes[..bytes.len().min(1024)];
    let text = head.trim_ascii_start();
    text.len() >= 5 && text[..5].eq_ignore_ascii_case(b"solid") && !head.contains(&0)
}

fn read_binary(bytes: &[u8], check: &VertexCheck) -> Result<TriMesh, String> {
    let count = (bytes.len() - 84) / 50;
    if count > MAX_TRIANGLES {
        return Err(too_many(count));
    }
    let mut mesh = TriMesh {
        vertices: Vec::with_capacity(count * 3),
        triangles: Vec::with_capacity(count),
    };
    for (f, rec) in bytes[84..].chunks_exact(50).enumerate() {
        let float = |k: usize| {
            let b = &rec[12 + 4 * k..16 + 4 * k];
            f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        };
        push_facet(
            &mut mesh,
            f,
            |v| DVec3::new(float(3 * v), float(3 * v + 1), float(3 * v + 2)),
            check,
        )?;
    }
    Ok(mesh)
}

fn push_facet(
    mesh: &mut TriMesh,
    facet: usize,
    vertex: impl Fn(usize) -> DVec3,
    check: &VertexCheck,
) -> Result<(), String> {
    let base = mesh.vertices.len() as u32;
    for v in 0..3 {
        let p = check.to_mm(vertex(v), &|| format!("vertex {v} of facet {facet}"))?;
        mesh.vertices.push(p);
    }
    mesh.triangles.push([base, base + 1, base + 2]);
    Ok(())
}

fn too_many(count: usize) -> String {
    format!(
        "the mesh has more than {MAX_TRIANGLES} triangles ({count}): decimate it; an RSA model needs far fewer"
    )
}

/// A cursor over the words of the text, with the 1-based line number of the next word.
struct Words<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Words<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Words {
            bytes,
            pos: 0,
            line: 1,
        }
    }

    fn skip_blanks(&mut self) {
        while let Some(&b) = self.bytes.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
    }

    fn line(&mut self) -> usize {
        self.skip_blanks();
        self.line
    }

    fn peek(&mut self) -> Option<&'a [u8]> {
        self.skip_blanks();
        let rest = self.bytes.get(self.pos..).filter(|r| !r.is_empty())?;
        let len = rest
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .unwrap_or(rest.len());
        Some(&rest[..len])
    }

    fn advance(&mut self) {
        if let Some(w) = self.peek() {
            self.pos += w.len();
        }
    }

    fn expect(&mut self, word: &str) -> Result<(), String> {
        match self.peek() {
            Some(w) if w.eq_ignore_ascii_case(word.as_bytes()) => {
                self.advance();
                Ok(())
            }
            Some(_) => Err(format!("line {}: expected `{word}`", self.line())),
            None => Err(format!("the file ends where `{word}` was expected")),
        }
    }

    fn number(&mut self) -> Result<f64, String> {
        let line = self.line();
        let w = self
            .peek()
            .ok_or_else(|| "the file ends inside a facet".to_string())?;
        let value = std::str::from_utf8(w)
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
            .ok_or_else(|| format!("line {line}: expected a number"))?;
        self.advance();
        Ok(value)
    }

    /// Skips the rest of the current line (a solid's name).
    fn skip_line(&mut self) {
        while let Some(&b) = self.bytes.get(self.pos) {
            if b == b'\n' {
                break;
            }
            self.pos += 1;
        }
    }
}

fn read_ascii(bytes: &[u8], check: &VertexCheck) -> Result<TriMesh, String> {
    let mut words = Words::new(bytes);
    let mut mesh = TriMesh {
        vertices: Vec::new(),
        triangles: Vec::new(),
    };
    let mut facet = 0;
    while words.peek().is_some() {
        words.expect("solid")?;
        words.skip_line();
        loop {
            match words.peek() {
                Some(w) if w.eq_ignore_ascii_case(b"endsolid") => {
                    words.advance();
                    words.skip_line();
                    break;
                }
                Some(w) if w.eq_ignore_ascii_case(b"facet") => {
                    if facet >= MAX_TRIANGLES {
                        return Err(too_many(facet + 1));
                    }
                    words.advance();
                    words.expect("normal")?;
                    for _ in 0..3 {
                        words.number()?;
                    }
                    words.expect("outer")?;
                    words.expect("loop")?;
                    let mut corners = [DVec3::ZERO; 3];
                    for c in &mut corners {
                        words.expect("vertex")?;
                        *c = DVec3::new(words.number()?, words.number()?, words.number()?);
                    }
                    words.expect("endloop")?;
                    words.expect("endfacet")?;
                    push_facet(&mut mesh, facet, |v| corners[v], check)?;
                    facet += 1;
                }
                Some(_) => {
                    return Err(format!(
                        "line {}: expected `facet` or `endsolid`",
                        words.line()
                    ));
                }
                None => return Err("the file ends before `endsolid`".into()),
            }
        }
    }
    Ok(mesh)
}
