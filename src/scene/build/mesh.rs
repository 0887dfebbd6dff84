//! Mesh files (OBJ through tobj, PLY and Mitsuba's serialized format through
//! [`crate::io`]'s readers) turned into the scene's meshes: transformed to world space,
//! normals by the inverse transpose, texture coordinates flipped if asked, degenerate faces
//! dropped (with their face attributes), missing normals computed as Mitsuba does.

use crate::error::{Error, Result};
use crate::shape::mesh::angle_weighted_normals;
use crate::shape::Mesh;
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};
use std::path::Path;

/// Which reader a mesh file goes through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (tobj).
    Obj,
    /// Stanford PLY ([`crate::io::ply`]).
    Ply,
    /// Mitsuba's serialized format, one mesh of the file ([`crate::io::serialized`]).
    Serialized { shape_index: u32 },
}

/// How a mesh file is placed in the scene (Mitsuba's common mesh parameters).
#[derive(Clone, Copy, Debug)]
pub struct MeshOptions {
    pub to_world: DMat4,
    pub face_normals: bool,
    pub flip_tex_coords: bool,
    pub flip_normals: bool,
}

impl MeshOptions {
    pub fn new(
        to_world: DMat4,
        face_normals: bool,
        flip_tex_coords: bool,
        flip_normals: bool,
    ) -> Self {
        MeshOptions {
            to_world,
            face_normals,
            flip_tex_coords,
            flip_normals,
        }
    }
}

/// Loads a Wavefront OBJ with tobj (triangulated, single index), transforms it to world
/// space and drops faces with non-finite or coincident vertices (counted in a warning).
pub fn load_obj(
    path: &Path,
    to_world: DMat4,
    face_normals: bool,
    flip_tex_coords: bool,
    flip_normals: bool,
    warnings: &mut Vec<String>,
) -> Result<Mesh> {
    let options = MeshOptions::new(to_world, face_normals, flip_tex_coords, flip_normals);
    load_mesh(path, MeshFormat::Obj, &options, warnings)
}

/// Loads a mesh file of any supported format (see [`mesh_from_bytes`]).
pub fn load_mesh(
    path: &Path,
    format: MeshFormat,
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Result<Mesh> {
    let limits = crate::limits::current()?;
    let bytes = crate::io::read_file_limited(path, limits.file(crate::limits::Limit::MeshBytes))
        .map_err(|cause| Error::Io {
            path: path.to_path_buf(),
            cause,
        })?;
    mesh_from_bytes(&bytes, path, format, options, warnings)
}

/// [`load_obj`] on the file's contents; `path` names it in messages.
pub fn obj_from_bytes(
    bytes: &[u8],
    path: &Path,
    to_world: DMat4,
    face_normals: bool,
    flip_tex_coords: bool,
    flip_normals: bool,
    warnings: &mut Vec<String>,
) -> Result<Mesh> {
    let options = MeshOptions::new(to_world, face_normals, flip_tex_coords, flip_normals);
    mesh_from_bytes(bytes, path, MeshFormat::Obj, &options, warnings)
}

/// Reads a mesh file's contents (`path` names it in messages) and builds the scene's mesh:
/// positions transformed to world space, normals by the inverse transpose and normalised
/// (as Mitsuba does), texture coordinates flipped vertically if asked (v → 1 − v), faces
/// with non-finite or coincident vertices dropped (counted in a warning), and vertex normals
/// computed (angle-weighted, as Mitsuba) when the file has none and `face_normals` is off.
pub fn mesh_from_bytes(
    bytes: &[u8],
    path: &Path,
    format: MeshFormat,
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Result<Mesh> {
    let mesh_err = |message: String| Error::Mesh {
        path: path.to_path_buf(),
        message,
    };
    let data = match format {
        MeshFormat::Obj => obj_data(bytes).map_err(mesh_err)?,
        MeshFormat::Ply => {
            let mut w = Vec::new();
            let data = crate::io::ply::read_ply_with_warnings(bytes, &mut w).map_err(mesh_err)?;
            warnings.extend(w.into_iter().map(|m| format!("{}: {m}", path.display())));
            data
        }
        MeshFormat::Serialized { shape_index } => {
            crate::io::serialized::read_serialized(bytes, shape_index as usize).map_err(mesh_err)?
        }
    };
    Ok(mesh_from_data(&data, path, options, warnings))
}

/// The vertices, normals, texture coordinates and faces of an OBJ file (tobj: triangulated,
/// one index per vertex; every model of the file, in order).
fn obj_data(bytes: &[u8]) -> std::result::Result<crate::io::mesh::MeshData, String> {
    let mut reader = std::io::BufReader::new(bytes);
    let (models, _) = tobj::load_obj_buf(&mut reader, &tobj::GPU_LOAD_OPTIONS, |_| {
        Err(tobj::LoadError::GenericFailure) // materials are not used: skip .mtl files
    })
    .map_err(|e| e.to_string())?;
    let mut data = crate::io::mesh::MeshData::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let (mut all_normals, mut all_uvs) = (true, true);
    for model in &models {
        let m = &model.mesh;
        let base = data.positions.len();
        let nv = m.positions.len() / 3;
        all_normals &= m.normals.len() == nv * 3;
        all_uvs &= m.texcoords.len() == nv * 2;
        data.positions
            .extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        normals.extend(m.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]));
        uvs.extend(m.texcoords.chunks_exact(2).map(|t| [t[0], t[1]]));
        for f in m.indices.chunks(3) {
            let [a, b, c] = match f {
                [a, b, c] => [*a, *b, *c],
                _ => return Err("a face with fewer than three vertices".into()),
            };
            if [a, b, c].iter().any(|&i| i as usize >= nv) {
                return Err(format!("face index {} out of range", a.max(b).max(c)));
            }
            data.triangles
                .push([a, b, c].map(|i| (base + i as usize) as u32));
        }
    }
    let nv = data.positions.len();
    data.normals = (all_normals && normals.len() == nv && nv > 0).then_some(normals);
    data.uvs = (all_uvs && uvs.len() == nv && nv > 0).then_some(uvs);
    Ok(data)
}

/// The scene's mesh from file data (see [`mesh_from_bytes`]).
fn mesh_from_data(
    data: &crate::io::mesh::MeshData,
    path: &Path,
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Mesh {
    let to_world = options.to_world;
    let normal_matrix = DMat3::from_mat4(to_world).inverse().transpose();
    let positions: Vec<Vec3> = data
        .positions
        .iter()
        .map(|p| {
            to_world
                .transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .as_vec3()
        })
        .collect();
    let mut triangles = Vec::with_capacity(data.triangles.len());
    let mut kept_faces = Vec::with_capacity(data.triangles.len());
    let mut skipped = 0usize;
    for (f, idx) in data.triangles.iter().enumerate() {
        let p = idx.map(|i| positions[i as usize]);
        let finite = p.iter().all(|q| q.is_finite());
        let area2 = (p[1] - p[0])
            .as_dvec3()
            .cross((p[2] - p[0]).as_dvec3())
            .length();
        if finite && area2 > 0.0 && area2.is_finite() {
            triangles.push(*idx);
            kept_faces.push(f);
        } else {
            skipped += 1;
        }
    }
    if skipped > 0 {
        warnings.push(format!(
            "{}: skipped {skipped} degenerate or non-finite face(s)",
            path.display()
        ));
    }
    let normals = if options.face_normals {
        None
    } else if let Some(n) = &data.normals {
        Some(
            n.iter()
                .map(|n| {
                    let n = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
                    (normal_matrix * n).normalize_or_zero().as_vec3()
                })
                .collect(),
        )
    } else {
        Some(angle_weighted_normals(&positions, &triangles))
    };
    let uvs = data.uvs.as_ref().map(|uvs| {
        uvs.iter()
            .map(|t| {
                Vec2::new(
                    t[0],
                    if options.flip_tex_coords {
                        1.0 - t[1]
                    } else {
                        t[1]
                    },
                )
            })
            .collect()
    });
    let mut mesh = Mesh::new(positions, normals, uvs, triangles, options.flip_normals);
    // Attributes follow their faces (the degenerate ones dropped above).
    mesh.attributes = data
        .vertex_attributes
        .iter()
        .map(|a| crate::shape::mesh::MeshAttribute {
            name: a.name.clone(),
            channels: a.channels,
            per_face: false,
            values: a.values.clone(),
        })
        .chain(data.face_attributes.iter().map(|a| {
            crate::shape::mesh::MeshAttribute {
                name: a.name.clone(),
                channels: a.channels,
                per_face: true,
                values: kept_faces
                    .iter()
                    .flat_map(|&f| a.row(f).unwrap_or(&[]).iter().copied())
                    .collect(),
            }
        }))
        .collect();
    if mesh.triangles.is_empty() {
        warnings.push(format!(
            "{}: the mesh has no valid triangle",
            path.display()
        ));
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An OBJ file's vertex normals and texture coordinates reach the mesh data (a smooth
    /// mesh must not render faceted), and a file without them gives none.
    #[test]
    fn obj_normals_and_uvs_are_kept() {
        let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
                    vn 0 0 1\nvn 0 0.6 0.8\nvn 0.6 0 0.8\nf 1/1/1 2/2/2 3/3/3\n";
        let d = obj_data(obj).expect("parses");
        assert_eq!(d.triangles, vec![[0, 1, 2]]);
        let n = d.normals.expect("normals kept");
        assert_eq!(n.len(), 3);
        let mut sorted = n.clone();
        sorted.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(
            sorted,
            vec![[0.0, 0.0, 1.0], [0.0, 0.6, 0.8], [0.6, 0.0, 0.8]]
        );
        assert_eq!(d.uvs.expect("uvs kept").len(), 3);
        let plain = obj_data(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("parses");
        assert!(plain.normals.is_none() && plain.uvs.is_none());
    }
}
