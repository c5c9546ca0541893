//! A triangle mesh as Wavefront OBJ text (what XMALab loads as a rigid body's model).

use std::fmt::Write;

use crate::phantom::TriMesh;

/// `v x y z` per vertex (mm, the phantom's local frame), then `f a b c` per triangle (1-based,
/// counter-clockwise seen from outside).
pub fn obj(mesh: &TriMesh) -> String {
    let mut s = String::with_capacity(mesh.vertices.len() * 40 + mesh.triangles.len() * 24);
    s += "# written by ";
    s += &crate::output::program();
    s += "; mm, the phantom's local frame\n";
    for v in &mesh.vertices {
        let _ = writeln!(s, "v {} {} {}", v[0], v[1], v[2]);
    }
    for t in &mesh.triangles {
        let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_triangle_by_hand() {
        let m = TriMesh {
            vertices: vec![[0.0, 0.0, 0.0], [1.5, 0.0, 0.0], [0.0, 2.0, -1.0]],
            triangles: vec![[0, 1, 2]],
        };
        let text = obj(&m);
        let body: Vec<&str> = text.lines().skip(1).collect();
        assert_eq!(body, ["v 0 0 0", "v 1.5 0 0", "v 0 2 -1", "f 1 2 3"]);
    }
}
