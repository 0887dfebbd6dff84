//! The plain triangle-mesh data that the mesh file readers ([`super::ply`],
//! [`super::serialized`]) return.
//!
//! Everything is in the file's own coordinates and exactly as stored (converted to `f32` the
//! way Mitsuba 3.9.1 converts it): the caller applies `to_world`, normalises normals after the
//! transform (Mitsuba does `normalize(to_world * n)` for every vertex normal it keeps),
//! computes missing normals, flips texture coordinates if asked, and drops degenerate faces.
//! A reader guarantees only the structural invariants checked by [`MeshData::validate`]: every
//! per-vertex array has one entry per position, every index is in range, and every attribute
//! holds `channels` values per vertex or face.

/// A triangle mesh as read from a file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex normals as stored in the file (not normalised).
    pub normals: Option<Vec<[f32; 3]>>,
    /// Per-vertex texture coordinates as stored (not flipped).
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Vertex indices, each `< positions.len()`. Degenerate triangles are kept.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex attributes, named as Mitsuba names them (`vertex_color`, ...), in the order
    /// Mitsuba creates them.
    pub vertex_attributes: Vec<MeshAttribute>,
    /// Per-face attributes (`face_color`, ...), one row per entry of `triangles`.
    pub face_attributes: Vec<MeshAttribute>,
}

/// A named per-vertex or per-face attribute: `values` holds `channels` floats per row,
/// row after row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshAttribute {
    pub name: String,
    pub channels: usize,
    pub values: Vec<f32>,
}

impl MeshAttribute {
    /// The `channels` values of row `i` (a vertex or a face), if it exists.
    pub fn row(&self, i: usize) -> Option<&[f32]> {
        let start = i.checked_mul(self.channels)?;
        self.values.get(start..start.checked_add(self.channels)?)
    }
}

impl MeshData {
    /// Checks the invariants the readers promise: matching array lengths, indices in range,
    /// attribute sizes. Returns a one-line message on the first violation.
    pub fn validate(&self) -> Result<(), String> {
        let nv = self.positions.len();
        if let Some(n) = &self.normals {
            if n.len() != nv {
                return Err(format!("{} normals for {nv} vertices", n.len()));
            }
        }
        if let Some(uv) = &self.uvs {
            if uv.len() != nv {
                return Err(format!(
                    "{} texture coordinates for {nv} vertices",
                    uv.len()
                ));
            }
        }
        for (f, tri) in self.triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= nv) {
                return Err(format!(
                    "face {f} refers to vertex {i}, but there are only {nv} vertices"
                ));
            }
        }
        let nf = self.triangles.len();
        for (attrs, rows, kind) in [
            (&self.vertex_attributes, nv, "vertex"),
            (&self.face_attributes, nf, "face"),
        ] {
            for a in attrs {
                if a.channels == 0 || a.channels > 4 {
                    return Err(format!(
                        "{kind} attribute \"{}\" has {} channels (1 to 4 allowed)",
                        a.name, a.channels
                    ));
                }
                if Some(a.values.len()) != rows.checked_mul(a.channels) {
                    return Err(format!(
                        "{kind} attribute \"{}\" has {} values, expected {rows} x {}",
                        a.name,
                        a.values.len(),
                        a.channels
                    ));
                }
            }
        }
        Ok(())
    }

    /// The vertex attribute called `name`, if present.
    pub fn vertex_attribute(&self, name: &str) -> Option<&MeshAttribute> {
        self.vertex_attributes.iter().find(|a| a.name == name)
    }

    /// The face attribute called `name`, if present.
    pub fn face_attribute(&self, name: &str) -> Option<&MeshAttribute> {
        self.face_attributes.iter().find(|a| a.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> MeshData {
        MeshData {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            ..Default::default()
        }
    }

    #[test]
    fn validate_accepts_a_triangle_and_rejects_bad_indices_and_sizes() {
        let mut m = tri();
        assert_eq!(m.validate(), Ok(()));
        m.triangles.push([0, 1, 3]);
        assert!(m.validate().unwrap_err().contains("vertex 3"));
        let mut m = tri();
        m.normals = Some(vec![[0.0; 3]; 2]);
        assert!(m.validate().is_err());
        let mut m = tri();
        m.face_attributes.push(MeshAttribute {
            name: "face_x".into(),
            channels: 2,
            values: vec![1.0],
        });
        assert!(m.validate().is_err());
        m.face_attributes[0].values.push(2.0);
        assert_eq!(m.validate(), Ok(()));
        assert_eq!(
            m.face_attribute("face_x").unwrap().row(0),
            Some(&[1.0, 2.0][..])
        );
        assert_eq!(m.face_attribute("face_x").unwrap().row(1), None);
    }
}
