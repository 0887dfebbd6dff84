//! Turns a [`SceneDescription`] into a render-ready [`Scene`]: shapes tessellated or set up
//! in world space, meshes loaded (OBJ with tobj, PLY and Mitsuba's serialized format with
//! [`crate::io`]'s readers), materials and emitters resolved, one BVH built (two levels when
//! the scene instances shape groups).

use super::description::{
    BsdfDesc, EmitterDesc, FilterDesc, IntegratorDesc, SceneDescription, ShapeDesc, ShapeKind,
};
use super::Scene;
use crate::accel::{Accel, Group, Instance};
use crate::bsdf::{Bsdf, Diffuse, TwoSided};
use crate::camera::{fov_x_degrees, Camera, OrthographicCamera, PerspectiveCamera, ThinLens};
use crate::emitter::{
    AreaEmitter, ConstantEmitter, DirectionalEmitter, Emitter, EnvMapEmitter, PointEmitter,
    SpotEmitter,
};
use crate::error::{Error, Result};
use crate::film::Filter;
use crate::integrator::{DirectIntegrator, Integrator, PathIntegrator};
use crate::shape::mesh::angle_weighted_normals;
use crate::shape::{Cylinder, Disk, Mesh, SdfGrid, Shape, ShapeGeometry, Sphere};
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};
use std::path::Path;

/// Builds the scene in camera-relative coordinates: every transform is composed in f64 with
/// a translation that puts the camera at the origin before anything is rounded to f32. A scene
/// placed far from the world origin then keeps full f32 precision where it is seen, and renders
/// the same image as the same scene near the origin.
pub fn build(desc: &SceneDescription) -> Result<Scene> {
    let s = &desc.sensor;
    let shift = DMat4::from_translation(-s.to_world.transform_point3(DVec3::ZERO));
    let (width, height) = (s.film.width as usize, s.film.height as usize);
    let aspect = width as f64 / height as f64;
    let camera: Camera = if s.orthographic {
        OrthographicCamera::new(shift * s.to_world, aspect, s.near_clip, s.far_clip).into()
    } else {
        let mut camera = PerspectiveCamera::new(
            shift * s.to_world,
            fov_x_degrees(s.fov, s.fov_axis, aspect),
            aspect,
            s.near_clip,
            s.far_clip,
        );
        if let Some((aperture_radius, focus_distance)) = s.thin_lens {
            camera = camera.with_thin_lens(ThinLens {
                aperture_radius,
                focus_distance,
            });
        }
        camera.into()
    };
    let mut warnings = desc.warnings.clone();
    let mut shapes = Vec::new();
    let mut bsdfs = Vec::new();
    let mut emitters = Vec::new();
    let mut instances = Vec::new();
    for sd in &desc.shapes {
        if let ShapeKind::Instance { group } = sd.kind {
            let inst = Instance::new(group as u32, shift * sd.to_world).ok_or_else(|| {
                Error::scene(
                    &sd.location,
                    "to_world of this instance is degenerate (zero scale)",
                )
            })?;
            instances.push(inst);
            continue;
        }
        let geometry = shape_geometry(sd, shift, &mut warnings)?;
        let shape_index = shapes.len() as u32;
        bsdfs.push(bsdf(&sd.bsdf));
        let emitter = match &sd.emitter {
            None => None,
            Some(EmitterDesc::Area { radiance }) => {
                emitters.push(Emitter::Area(AreaEmitter {
                    shape: shape_index,
                    radiance: radiance.as_vec3(),
                }));
                Some((emitters.len() - 1) as u32)
            }
            Some(_) => {
                return Err(Error::scene(
                    &sd.location,
                    "only an area emitter can be attached to a shape",
                ))
            }
        };
        shapes.push(Shape {
            geometry,
            bsdf: (bsdfs.len() - 1) as u32,
            emitter,
        });
    }
    // Shape groups: their shapes follow the scene's own, in the group's space, each group with
    // its own hierarchy. (Groups hold no emitters: the description refuses them.)
    let top_level = shapes.len();
    let mut groups = Vec::new();
    for g in &desc.shape_groups {
        let first = shapes.len();
        for sd in &g.shapes {
            let geometry = shape_geometry(sd, DMat4::IDENTITY, &mut warnings)?;
            bsdfs.push(bsdf(&sd.bsdf));
            shapes.push(Shape {
                geometry,
                bsdf: (bsdfs.len() - 1) as u32,
                emitter: None,
            });
        }
        groups.push(Group {
            accel: Accel::build_with_instances(&shapes, first..shapes.len(), vec![], vec![]),
        });
    }
    let accel = Accel::build_with_instances(&shapes, 0..top_level, instances, groups);
    let mut environment = None;
    for e in &desc.emitters {
        if matches!(e, EmitterDesc::Constant { .. } | EmitterDesc::EnvMap { .. }) {
            environment = Some(emitters.len() as u32);
        }
        emitters.push(scene_emitter(e, shift)?);
    }
    if emitters.is_empty() {
        warnings.push("the scene has no emitter: the image will be black".into());
    }
    let bounding_sphere = bounding_sphere(&accel);
    let integrator = match desc.integrator {
        IntegratorDesc::Path {
            max_depth,
            rr_depth,
            hide_emitters,
        } => Integrator::Path(PathIntegrator {
            max_depth: if max_depth < 0 {
                u32::MAX
            } else {
                max_depth.min(u32::MAX as i64) as u32
            },
            rr_depth: rr_depth.clamp(1, u32::MAX as i64) as u32,
            hide_emitters,
        }),
        IntegratorDesc::Direct {
            emitter_samples,
            bsdf_samples,
            hide_emitters,
        } => Integrator::Direct(DirectIntegrator::new(
            emitter_samples,
            bsdf_samples,
            hide_emitters,
        )),
    };
    Ok(Scene {
        shapes,
        bsdfs,
        emitters,
        accel,
        camera,
        width,
        height,
        filter: match s.film.rfilter {
            FilterDesc::Box => Filter::Box,
            FilterDesc::Tent { radius } => Filter::Tent { radius },
            FilterDesc::Gaussian { stddev } => Filter::Gaussian { stddev },
        },
        sample_count: s.sampler.sample_count,
        seed: s.sampler.seed,
        integrator,
        warnings,
        environment,
        bounding_sphere,
    })
}

/// A sphere around everything in the scene (centre of the hierarchy's bounding box, half
/// its diagonal); radius 1 around the origin for a scene without shapes.
fn bounding_sphere(accel: &Accel) -> (Vec3, f32) {
    match accel.bounds {
        Some((lo, hi)) if lo.is_finite() && hi.is_finite() => {
            let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
            let c = (lo + hi) * 0.5;
            (c.as_vec3(), ((hi - lo).length() * 0.5).max(1e-6) as f32)
        }
        _ => (Vec3::ZERO, 1.0),
    }
}

/// An emitter declared at the scene level; `shift` maps world space to the camera-relative
/// space the scene is built in (positions move, directions do not).
fn scene_emitter(e: &EmitterDesc, shift: DMat4) -> Result<Emitter> {
    Ok(match e {
        EmitterDesc::Area { .. } => {
            return Err(Error::Invalid(
                "an area emitter must be attached to a shape".into(),
            ))
        }
        EmitterDesc::Point {
            position,
            intensity,
        } => Emitter::Point(PointEmitter {
            position: shift.transform_point3(*position).as_vec3(),
            intensity: intensity.as_vec3(),
        }),
        EmitterDesc::Spot {
            to_world,
            intensity,
            cutoff_angle,
            beam_width,
        } => Emitter::Spot(SpotEmitter {
            position: (shift * *to_world).transform_point3(DVec3::ZERO).as_vec3(),
            axis: to_world
                .transform_vector3(DVec3::Z)
                .try_normalize()
                .unwrap_or(DVec3::Z)
                .as_vec3(),
            intensity: intensity.as_vec3(),
            cutoff_angle: cutoff_angle.to_radians() as f32,
            beam_width: beam_width.to_radians() as f32,
        }),
        EmitterDesc::Directional {
            direction,
            irradiance,
        } => Emitter::Directional(DirectionalEmitter {
            direction: direction.as_vec3(),
            irradiance: irradiance.as_vec3(),
        }),
        EmitterDesc::Constant { radiance } => Emitter::Constant(ConstantEmitter {
            radiance: radiance.as_vec3(),
        }),
        EmitterDesc::EnvMap {
            filename,
            scale,
            to_world,
            location,
        } => {
            let img = crate::io::exr::read(filename)?;
            if img
                .rgb
                .iter()
                .any(|t| t.iter().any(|x| !x.is_finite() || *x < 0.0))
            {
                return Err(Error::scene(
                    location,
                    format!(
                        "{}: the environment map has negative or non-finite texels",
                        filename.display()
                    ),
                ));
            }
            // Keep only the rotation (Mitsuba's to_world for an envmap is a rotation): the
            // nearest orthonormal frame by Gram-Schmidt, so that the map's sampling density
            // stays exact even when the transform also scales or shears (a rotation about a
            // non-unit axis does, see scene::xml's `rotate`).
            let m = DMat3::from_mat4(*to_world);
            let x = m.x_axis.normalize_or_zero();
            let y = (m.y_axis - x * x.dot(m.y_axis)).normalize_or_zero();
            let z = x.cross(y) * m.determinant().signum();
            if x == DVec3::ZERO || y == DVec3::ZERO {
                return Err(Error::scene(
                    location,
                    "to_world of the environment map is degenerate",
                ));
            }
            let rot = DMat3::from_cols(x, y, z).as_mat3();
            Emitter::EnvMap(
                EnvMapEmitter::new(img.width, img.height, &img.rgb, *scale as f32, rot)
                    .ok_or_else(|| {
                        Error::scene(
                            location,
                            format!(
                                "{}: an environment map needs at least 1x2 pixels",
                                filename.display()
                            ),
                        )
                    })?,
            )
        }
    })
}

fn bsdf(d: &BsdfDesc) -> Bsdf {
    match d {
        BsdfDesc::Diffuse { reflectance } => Bsdf::Diffuse(Diffuse {
            reflectance: reflectance.as_vec3(),
        }),
        BsdfDesc::TwoSided { front, back } => Bsdf::TwoSided(TwoSided {
            front: Box::new(bsdf(front)),
            back: Box::new(bsdf(back)),
        }),
        BsdfDesc::Conductor {
            eta,
            k,
            specular_reflectance,
        } => Bsdf::Conductor(crate::bsdf::Conductor {
            eta: eta.as_vec3(),
            k: k.as_vec3(),
            specular_reflectance: specular_reflectance.as_vec3(),
        }),
        BsdfDesc::RoughConductor {
            distribution,
            eta,
            k,
            specular_reflectance,
        } => Bsdf::RoughConductor(crate::bsdf::RoughConductor {
            distribution: microfacet(distribution),
            eta: eta.as_vec3(),
            k: k.as_vec3(),
            specular_reflectance: specular_reflectance.as_vec3(),
        }),
        BsdfDesc::Dielectric {
            int_ior,
            ext_ior,
            specular_reflectance,
            specular_transmittance,
        } => Bsdf::Dielectric(crate::bsdf::Dielectric {
            eta: (int_ior / ext_ior) as f32,
            specular_reflectance: specular_reflectance.as_vec3(),
            specular_transmittance: specular_transmittance.as_vec3(),
        }),
        BsdfDesc::ThinDielectric {
            int_ior,
            ext_ior,
            specular_reflectance,
            specular_transmittance,
        } => Bsdf::ThinDielectric(crate::bsdf::ThinDielectric {
            eta: (int_ior / ext_ior) as f32,
            specular_reflectance: specular_reflectance.as_vec3(),
            specular_transmittance: specular_transmittance.as_vec3(),
        }),
        BsdfDesc::RoughDielectric {
            distribution,
            int_ior,
            ext_ior,
            specular_reflectance,
            specular_transmittance,
        } => Bsdf::RoughDielectric(crate::bsdf::RoughDielectric {
            distribution: microfacet(distribution),
            eta: (int_ior / ext_ior) as f32,
            specular_reflectance: specular_reflectance.as_vec3(),
            specular_transmittance: specular_transmittance.as_vec3(),
        }),
        BsdfDesc::Plastic {
            int_ior,
            ext_ior,
            diffuse_reflectance,
            specular_reflectance,
            nonlinear,
        } => Bsdf::Plastic(crate::bsdf::Plastic::new(
            (int_ior / ext_ior) as f32,
            diffuse_reflectance.as_vec3(),
            specular_reflectance.as_vec3(),
            *nonlinear,
        )),
        BsdfDesc::RoughPlastic {
            distribution,
            int_ior,
            ext_ior,
            diffuse_reflectance,
            specular_reflectance,
            nonlinear,
        } => Bsdf::RoughPlastic(crate::bsdf::RoughPlastic::new(
            microfacet(distribution),
            (int_ior / ext_ior) as f32,
            diffuse_reflectance.as_vec3(),
            specular_reflectance.as_vec3(),
            *nonlinear,
        )),
    }
}

fn microfacet(d: &crate::scene::description::MicrofacetDesc) -> crate::bsdf::Microfacet {
    use crate::scene::description::MicrofacetKind;
    crate::bsdf::Microfacet::new(
        match d.kind {
            MicrofacetKind::Beckmann => crate::bsdf::MicrofacetType::Beckmann,
            MicrofacetKind::Ggx => crate::bsdf::MicrofacetType::Ggx,
        },
        d.alpha_u as f32,
        d.alpha_v as f32,
        d.sample_visible,
    )
}

/// Local-space quads (four corners, counter-clockwise seen from the side the normal points
/// to, with their texture coordinates) of Mitsuba's `rectangle` ([-1,1]² at z = 0, normal +z,
/// uv = (x + 1, y + 1) / 2) and `cube` ([-1,1]³, every face mapped onto [0,1]² with the corner
/// order and uvs of Mitsuba's `cube.cpp`, which decide the dp/du of its shading frames).
fn quads(kind: &ShapeKind) -> Vec<([DVec3; 4], [Vec2; 4])> {
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    match kind {
        ShapeKind::Rectangle => vec![(
            [
                v(-1.0, -1.0, 0.0),
                v(1.0, -1.0, 0.0),
                v(1.0, 1.0, 0.0),
                v(-1.0, 1.0, 0.0),
            ],
            [
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 1.0),
            ],
        )],
        ShapeKind::Cube => {
            let uv = [
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(0.0, 0.0),
            ];
            let faces: [[(f64, f64, f64); 4]; 6] = [
                [
                    (1., -1., -1.),
                    (1., -1., 1.),
                    (-1., -1., 1.),
                    (-1., -1., -1.),
                ],
                [(1., 1., -1.), (-1., 1., -1.), (-1., 1., 1.), (1., 1., 1.)],
                [(1., -1., -1.), (1., 1., -1.), (1., 1., 1.), (1., -1., 1.)],
                [(1., -1., 1.), (1., 1., 1.), (-1., 1., 1.), (-1., -1., 1.)],
                [
                    (-1., -1., 1.),
                    (-1., 1., 1.),
                    (-1., 1., -1.),
                    (-1., -1., -1.),
                ],
                [
                    (1., 1., -1.),
                    (1., -1., -1.),
                    (-1., -1., -1.),
                    (-1., 1., -1.),
                ],
            ];
            faces
                .iter()
                .map(|f| (f.map(|(x, y, z)| v(x, y, z)), uv))
                .collect()
        }
        _ => Vec::new(),
    }
}

/// `shift` maps world space to the camera-relative space the scene is built in.
fn shape_geometry(
    sd: &ShapeDesc,
    shift: DMat4,
    warnings: &mut Vec<String>,
) -> Result<ShapeGeometry> {
    let m = shift * sd.to_world;
    let degenerate = || {
        Error::scene(
            &sd.location,
            "to_world of this shape is degenerate (zero scale)",
        )
    };
    match &sd.kind {
        ShapeKind::Rectangle | ShapeKind::Cube => {
            if m.determinant() == 0.0 {
                return Err(degenerate());
            }
            // A mirroring transform reverses the winding; keep normals pointing where the
            // transformed local normal points, as Mitsuba does.
            let mirrored = m.determinant() < 0.0;
            let mut positions = Vec::new();
            let mut uvs = Vec::new();
            let mut triangles = Vec::new();
            for (q, uv) in quads(&sd.kind) {
                let base = positions.len() as u32;
                positions.extend(q.iter().map(|p| m.transform_point3(*p).as_vec3()));
                uvs.extend(uv);
                let (a, b) = if mirrored {
                    ([0, 2, 1], [2, 0, 3])
                } else {
                    ([0, 1, 2], [2, 3, 0])
                };
                triangles.push(a.map(|i| base + i));
                triangles.push(b.map(|i| base + i));
            }
            Ok(ShapeGeometry::Mesh(Mesh::new(
                positions,
                None,
                Some(uvs),
                triangles,
                sd.flip_normals,
            )))
        }
        ShapeKind::Disk => Disk::new(m, sd.flip_normals)
            .map(ShapeGeometry::Disk)
            .ok_or_else(degenerate),
        ShapeKind::Sphere { center, radius } => {
            // Mitsuba: to_world · translate(center) · scale(radius), then centre and radius
            // are read back from the combined similarity transform.
            let full =
                m * DMat4::from_translation(*center) * DMat4::from_scale(DVec3::splat(*radius));
            let axes = [0, 1, 2].map(|i| full.col(i).truncate());
            let r = axes[0].length();
            let similar = axes.iter().all(|a| (a.length() - r).abs() <= 1e-6 * r)
                && axes[0].dot(axes[1]).abs() <= 1e-6 * r * r
                && axes[1].dot(axes[2]).abs() <= 1e-6 * r * r
                && axes[0].dot(axes[2]).abs() <= 1e-6 * r * r;
            if !(r > 0.0 && r.is_finite() && similar) {
                return Err(Error::scene(
                    &sd.location,
                    "a sphere's to_world may only rotate, translate and scale uniformly",
                ));
            }
            let rotation = DMat3::from_cols(axes[0] / r, axes[1] / r, axes[2] / r);
            Ok(ShapeGeometry::Sphere(Sphere {
                center: full.transform_point3(DVec3::ZERO),
                radius: r,
                flip_normals: sd.flip_normals,
                rotation,
            }))
        }
        ShapeKind::Cylinder { p0, p1, radius } => {
            let c = Cylinder::new(*p0, *p1, *radius, m, sd.flip_normals).ok_or_else(degenerate)?;
            for w in c.warnings() {
                warnings.push(format!("{}: {w}", sd.location));
            }
            Ok(ShapeGeometry::Cylinder(c))
        }
        ShapeKind::Ply {
            filename,
            face_normals,
            flip_tex_coords,
        } => {
            let options = MeshOptions::new(m, *face_normals, *flip_tex_coords, sd.flip_normals);
            load_mesh(filename, MeshFormat::Ply, &options, warnings).map(ShapeGeometry::Mesh)
        }
        ShapeKind::Serialized {
            filename,
            shape_index,
            face_normals,
        } => {
            // Mitsuba's serialized meshes keep their texture coordinates as stored.
            let options = MeshOptions::new(m, *face_normals, false, sd.flip_normals);
            let format = MeshFormat::Serialized {
                shape_index: *shape_index,
            };
            load_mesh(filename, format, &options, warnings).map(ShapeGeometry::Mesh)
        }
        ShapeKind::SdfGrid {
            filename,
            analytic_normals,
        } => {
            let data = crate::io::vol::read_vol(filename).map_err(|message| Error::Mesh {
                path: filename.clone(),
                message,
            })?;
            if data.res[0] != data.res[2] {
                // Mitsuba 3.9.1 swaps the x and z voxel sizes: such a grid renders empty
                // there (penumbra renders the grid the file describes).
                warnings.push(format!(
                    "{}: an SDF grid of {}x{}x{} samples renders differently in Mitsuba 3.9.1, which mixes up its x and z resolutions",
                    filename.display(),
                    data.res[0],
                    data.res[1],
                    data.res[2]
                ));
            }
            let normals = if *analytic_normals {
                crate::shape::sdfgrid::SdfNormals::Analytic
            } else {
                crate::shape::sdfgrid::SdfNormals::Smooth
            };
            SdfGrid::new(data, m, normals, sd.flip_normals)
                .map(|g| ShapeGeometry::SdfGrid(Box::new(g)))
                .map_err(|e| Error::scene(&sd.location, e))
        }
        ShapeKind::Instance { .. } => unreachable!("instances are not shapes"),
        ShapeKind::Obj {
            filename,
            face_normals,
            flip_tex_coords,
        } => load_obj(
            filename,
            m,
            *face_normals,
            *flip_tex_coords,
            sd.flip_normals,
            warnings,
        )
        .map(ShapeGeometry::Mesh),
    }
}

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
    let bytes =
        crate::io::read_file_limited(path, crate::io::MAX_MESH_FILE_BYTES).map_err(|cause| {
            Error::Io {
                path: path.to_path_buf(),
                cause,
            }
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
    let mut skipped = 0usize;
    for idx in &data.triangles {
        let p = idx.map(|i| positions[i as usize]);
        let finite = p.iter().all(|q| q.is_finite());
        let area2 = (p[1] - p[0])
            .as_dvec3()
            .cross((p[2] - p[0]).as_dvec3())
            .length();
        if finite && area2 > 0.0 && area2.is_finite() {
            triangles.push(*idx);
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
    let mesh = Mesh::new(positions, normals, uvs, triangles, options.flip_normals);
    if mesh.triangles.is_empty() {
        warnings.push(format!(
            "{}: the mesh has no valid triangle",
            path.display()
        ));
    }
    mesh
}
