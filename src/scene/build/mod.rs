//! Turns a [`SceneDescription`] into a render-ready [`Scene`]: shapes tessellated or set up
//! in world space, meshes loaded (OBJ with tobj, PLY and Mitsuba's serialized format with
//! [`crate::io`]'s readers), materials and emitters resolved, one BVH built (two levels when
//! the scene instances shape groups).

mod material;
mod mesh;

pub use mesh::{load_mesh, load_obj, mesh_from_bytes, obj_from_bytes, MeshFormat, MeshOptions};

use super::description::{
    EmitterDesc, FilterDesc, IntegratorDesc, MediumDesc, PhaseDesc, SceneDescription, ShapeDesc,
    ShapeKind, VolumeDesc, NO_INTEGRATOR_WARNING,
};
use super::Scene;
use crate::accel::{Accel, Group, Instance};
use crate::camera::{
    fov_x_degrees, Camera, FilmWindow, OrthographicCamera, PerspectiveCamera, ThinLens,
};
use crate::emitter::{
    AreaEmitter, ConstantEmitter, DirectionalEmitter, Emitter, EnvMapEmitter, PointEmitter,
    ProjectorEmitter, SpotEmitter,
};
use crate::error::{Error, Result};
use crate::film::Filter;
use crate::medium::{Heterogeneous, Homogeneous, Medium, MediumKind};
use crate::phase::{HenyeyGreenstein, PhaseFunction};
use crate::sampler::Sampler;
use crate::sampling::Distribution1D;
use crate::shape::{Cylinder, Disk, Mesh, SdfGrid, Shape, ShapeGeometry, Sphere};
use crate::spectrum::Mode;
use crate::texture::bitmap::Wrap;
use crate::texture::ColorValue;
use crate::volume::{constant::ConstVolume, GridVolume, Volume};
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};
use rayon::prelude::*;

/// Builds the scene in camera-relative coordinates: every transform is composed in f64 with
/// a translation that puts the camera at the origin before anything is rounded to f32. A scene
/// placed far from the world origin then keeps full f32 precision where it is seen, and renders
/// the same image as the same scene near the origin.
pub fn build(desc: &SceneDescription) -> Result<Scene> {
    if let (Mode::Rgb, Some(what)) = (desc.mode, &desc.spectral_only) {
        return Err(Error::Invalid(format!(
            "{what} renders in spectral mode only (Mitsuba's RGB variants refuse it too): render with --mode spectral"
        )));
    }
    let s = &desc.sensor;
    let shift = DMat4::from_translation(-s.to_world.transform_point3(DVec3::ZERO));
    // The image is the film's crop window; the camera's projection is the whole film's.
    let (width, height) = (s.film.crop_size.0 as usize, s.film.crop_size.1 as usize);
    let aspect = s.film.width as f64 / s.film.height as f64;
    let window = FilmWindow::new(
        (s.film.width, s.film.height),
        s.film.crop_offset,
        s.film.crop_size,
        s.principal_point,
    );
    let camera: Camera = if s.orthographic {
        OrthographicCamera::new(shift * s.to_world, aspect, s.near_clip, s.far_clip)
            .with_window(window)
            .into()
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
        camera.with_window(window).into()
    };
    let mut warnings = desc.warnings.clone();
    if desc.integrator_missing {
        warnings.push(NO_INTEGRATOR_WARNING.into());
    }
    let mut shapes = Vec::new();
    let mut materials = material::MaterialBuilder::default();
    materials.shift = shift;
    materials.mode = desc.mode;
    let mut emitters = Vec::new();
    let mut emitter_weights = Vec::new();
    let mut instances = Vec::new();
    // Meshes are read and transformed in parallel (a scene of hundreds of PLY files, such as
    // Mitsuba's LEGO tutorial, spends its load there besides the BVH build), then taken in
    // description order, with their warnings, exactly as a serial load would.
    let mut geometries: Vec<Option<(Result<ShapeGeometry>, Vec<String>)>> = desc
        .shapes
        .par_iter()
        .map(|sd| {
            if matches!(sd.kind, ShapeKind::Instance { .. }) {
                return None;
            }
            let mut w = Vec::new();
            Some((shape_geometry(sd, shift, &mut w), w))
        })
        .collect();
    for (sd, loaded) in desc.shapes.iter().zip(geometries.iter_mut()) {
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
        // (every shape but an instance was loaded above)
        let Some((geometry, w)) = loaded.take() else {
            continue;
        };
        warnings.extend(w);
        let mut geometry = geometry?;
        if desc.mode == crate::spectrum::Mode::Spectral {
            if let ShapeGeometry::Mesh(m) = &mut geometry {
                m.upsample_color_attributes();
            }
        }
        let shape_index = shapes.len() as u32;
        let material = materials
            .material(&sd.bsdf)
            .map_err(|e| Error::within(&sd.location, e))?;
        shapes.push(Shape {
            geometry,
            material,
            emitter: None,
            interior: sd.interior.map(|i| i as u32),
            exterior: sd.exterior.map(|i| i as u32),
        });
        match &sd.emitter {
            None => {}
            Some(EmitterDesc::Area { radiance }) => {
                let mut radiance = materials
                    .texture_for(radiance, crate::texture::Lookup::Spectrum)
                    .map_err(|e| Error::within(&sd.location, e))?;
                if let crate::texture::Texture::Bitmap(b) = &mut radiance {
                    b.prepare_sampling();
                }
                let area = AreaEmitter::new(shape_index, radiance, &shapes).ok_or_else(|| {
                    Error::scene(
                        &sd.location,
                        "a textured area emitter needs a shape with texture coordinates (a mesh with uvs or an analytic shape; not an SDF grid)",
                    )
                })?;
                emitters.push(Emitter::Area(area));
                emitter_weights.push(sd.emitter_weight);
                shapes[shape_index as usize].emitter = Some((emitters.len() - 1) as u32);
            }
            Some(_) => {
                return Err(Error::scene(
                    &sd.location,
                    "only an area emitter can be attached to a shape",
                ))
            }
        }
    }
    // Shape groups: their shapes follow the scene's own, in the group's space, each group with
    // its own hierarchy. (Groups hold no emitters: the description refuses them.)
    let top_level = shapes.len();
    let mut groups = Vec::new();
    for g in &desc.shape_groups {
        let first = shapes.len();
        for sd in &g.shapes {
            let mut geometry = shape_geometry(sd, DMat4::IDENTITY, &mut warnings)?;
            if desc.mode == crate::spectrum::Mode::Spectral {
                if let ShapeGeometry::Mesh(m) = &mut geometry {
                    m.upsample_color_attributes();
                }
            }
            let material = materials
                .material(&sd.bsdf)
                .map_err(|e| Error::within(&sd.location, e))?;
            shapes.push(Shape {
                geometry,
                material,
                emitter: None,
                interior: None,
                exterior: None,
            });
        }
        groups.push(Group {
            accel: Accel::build_with_instances(&shapes, first..shapes.len(), vec![], vec![]),
        });
    }
    let accel = Accel::build_with_instances(&shapes, 0..top_level, instances, groups);
    let mut environment = None;
    for (e, w) in desc.emitters.iter().zip(&desc.emitter_weights) {
        if matches!(e, EmitterDesc::Constant { .. } | EmitterDesc::EnvMap { .. }) {
            environment = Some(emitters.len() as u32);
        }
        emitters.push(scene_emitter(e, shift, &mut materials)?);
        emitter_weights.push(*w);
    }
    // Mitsuba chooses emitters uniformly unless a sampling weight is not 1.
    let emitter_weights = if emitter_weights.iter().all(|&w| w == 1.0) {
        None
    } else {
        Some(Distribution1D::new(emitter_weights).ok_or_else(|| {
            Error::Invalid(
                "the emitters' sampling weights are all 0: no emitter can be sampled".into(),
            )
        })?)
    };
    if emitters.is_empty() {
        warnings.push("the scene has no emitter: the image will be black".into());
    }
    let bounding_sphere = bounding_sphere(&accel);
    // Emission is held in f32: a radiance (or its product with a scale) beyond its range is
    // infinite there, and every sample it reaches would be dropped as non-finite.
    for (i, e) in emitters.iter().enumerate() {
        if !e.power(&shapes, bounding_sphere.1 as f64).is_finite() {
            return Err(Error::Invalid(format!(
                "emitter {} of the scene ({}): its emission overflows the single-precision range (3.4e38) that penumbra renders in",
                i + 1,
                e.plugin_name()
            )));
        }
    }
    let media = desc
        .media
        .iter()
        .map(|m| medium(m, shift, desc.mode).map_err(|e| Error::within(&m.location, e)))
        .collect::<Result<Vec<_>>>()?;
    let (sampler, rounded) = Sampler::new(s.sampler.kind, s.sampler.sample_count);
    warnings.extend(rounded);
    let shadow_passthrough = !media.is_empty()
        || materials.materials.iter().any(|m| {
            matches!(
                m,
                crate::material::Material::Null
                    | crate::material::Material::Mask { .. }
                    | crate::material::Material::Leaf {
                        template: crate::bsdf::Bsdf::ThinDielectric(_),
                        ..
                    }
            )
        });
    let mut scene = Scene {
        mode: desc.mode,
        shadow_passthrough,
        uniform_bsdfs: Scene::build_uniform_bsdfs(&materials.materials),
        shapes,
        materials: materials.materials,
        emitters,
        emitter_weights,
        accel,
        camera,
        width,
        height,
        film_origin: s.film.crop_offset,
        film_size: (s.film.width, s.film.height),
        sample_border: 0,
        filter: match s.film.rfilter {
            FilterDesc::Box => Filter::Box,
            FilterDesc::Tent { radius } => Filter::Tent { radius },
            FilterDesc::Gaussian { stddev } => Filter::Gaussian { stddev },
        },
        sample_count: sampler.sample_count,
        sampler,
        seed: s.sampler.seed,
        world_origin: s.to_world.transform_point3(DVec3::ZERO).as_vec3(),
        warnings,
        environment,
        bounding_sphere,
        media,
        camera_medium: s.medium.map(|i| i as u32),
    };
    if s.film.sample_border {
        // Camera-path integrators sample the border; light tracing splats wherever its paths
        // land and SPPM's visible points are the image's own pixels.
        match &desc.integrator {
            IntegratorDesc::Sppm { .. } => scene.warnings.push(
                "sample_border is ignored by sppm: its visible points are the image's pixels"
                    .into(),
            ),
            IntegratorDesc::ParticleTracer { .. } => {}
            _ => scene.sample_border = scene.filter.border(),
        }
    }
    Ok(scene)
}

/// A medium of the scene; `shift` maps world space to the camera-relative space the scene is
/// built in (volumes are placed by their `to_world`); `mode` decides what the volumes hold.
fn medium(m: &MediumDesc, shift: DMat4, mode: Mode) -> Result<Medium> {
    let sigma_t = volume(&m.sigma_t, shift, mode)?;
    let albedo = volume(&m.albedo, shift, mode)?;
    if mode == Mode::Spectral {
        // A medium looks its volumes up as spectra.
        if let Some(e) = raw_grid_refusal(&sigma_t).or_else(|| raw_grid_refusal(&albedo)) {
            return Err(Error::Invalid(e));
        }
    }
    let scale = m.scale as f32;
    let kind = if m.homogeneous {
        MediumKind::Homogeneous(Homogeneous {
            sigma_t,
            albedo,
            scale,
        })
    } else {
        MediumKind::Heterogeneous(Heterogeneous::new(sigma_t, albedo, scale))
    };
    Ok(Medium {
        kind,
        phase: match m.phase {
            PhaseDesc::Isotropic => PhaseFunction::Isotropic,
            PhaseDesc::HenyeyGreenstein { g } => {
                PhaseFunction::HenyeyGreenstein(HenyeyGreenstein { g: g as f32 })
            }
        },
        sample_emitters: m.sample_emitters,
    })
}

/// A volume as `mode` renders it: in spectral mode constants hold their spectra and
/// three-channel grids are converted to spectra ([`GridVolume::to_spectral`]) unless `raw`
/// (then they can only be looked up as numbers: see [`raw_grid_refusal`]).
pub(super) fn volume(v: &VolumeDesc, shift: DMat4, mode: Mode) -> Result<Volume> {
    Ok(match v {
        VolumeDesc::Constant { value, to_world } => Volume::Constant(ConstVolume::new(
            ColorValue::new(value, mode),
            (shift * *to_world).as_mat4(),
        )),
        VolumeDesc::Grid {
            filename,
            to_world,
            use_grid_bbox,
            trilinear,
            wrap,
            max_value,
            raw,
        } => {
            let bad = |message: String| Error::Mesh {
                path: filename.clone(),
                message,
            };
            let data = crate::io::vol::read_vol(filename).map_err(bad)?;
            let wrap = Wrap::from_name(wrap).map_err(Error::Invalid)?;
            let grid = GridVolume::new(
                data,
                (shift * *to_world).as_mat4(),
                *use_grid_bbox,
                *trilinear,
                wrap,
            )
            .map_err(bad)?;
            let mut grid = Box::new(grid);
            if mode == Mode::Spectral && !*raw {
                grid.to_spectral();
            }
            if let Some(m) = max_value {
                grid.max = *m as f32;
            }
            Volume::Grid(grid)
        }
    })
}

/// Why a volume of spectral mode cannot be looked up as a spectrum: a three-channel grid
/// with `raw="true"` (Mitsuba's `gridvolume` refuses it too).
pub(super) fn raw_grid_refusal(v: &Volume) -> Option<String> {
    match v {
        Volume::Grid(g) if g.channels() == 3 && !g.is_spectral() => Some(
            "a three-channel gridvolume with raw=\"true\" cannot be looked up as a spectrum in spectral mode (Mitsuba refuses it too); drop raw=\"true\"".into(),
        ),
        _ => None,
    }
}

/// An environment map's texels as linear RGB, from any image format Mitsuba's `envmap` reads
/// (its `Bitmap::convert` to linear float RGB): 8- and 16-bit images are sRGB-decoded, grey
/// becomes RGB, alpha is dropped, XYZ converted ([`crate::io::image`]).
fn envmap_texels(path: &std::path::Path) -> Result<crate::io::exr::RgbImage> {
    let img = crate::io::image::read(path).map_err(|message| Error::Image {
        path: path.to_path_buf(),
        message,
    })?;
    let decode = img.samples.is_integer();
    let value = |i: usize| {
        let v = img.samples.value(i);
        if decode {
            crate::spectrum::srgb_to_linear(v as f64) as f32
        } else {
            v
        }
    };
    let rgb = (0..img.width * img.height)
        .map(|p| {
            if img.channels == 1 {
                [value(p); 3]
            } else {
                [value(3 * p), value(3 * p + 1), value(3 * p + 2)]
            }
        })
        .collect();
    Ok(crate::io::exr::RgbImage {
        width: img.width,
        height: img.height,
        rgb,
        variance: None,
        attributes: Default::default(),
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
fn scene_emitter(
    e: &EmitterDesc,
    shift: DMat4,
    textures: &mut material::MaterialBuilder,
) -> Result<Emitter> {
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
            intensity: ColorValue::new(intensity, textures.mode),
        }),
        EmitterDesc::Spot {
            to_world,
            intensity,
            cutoff_angle,
            beam_width,
            texture,
        } => {
            let texture = match texture {
                Some(t) => Some(textures.texture_for(t, crate::texture::Lookup::Spectrum)?),
                None => None,
            };
            Emitter::Spot(
                SpotEmitter::new(
                    shift * *to_world,
                    ColorValue::new(intensity, textures.mode),
                    *cutoff_angle,
                    *beam_width,
                    texture,
                )
                .ok_or_else(|| Error::Invalid("to_world of a spot light is degenerate".into()))?,
            )
        }
        EmitterDesc::Projector {
            to_world,
            irradiance,
            scale,
            fov,
            fov_axis,
        } => {
            let irradiance = textures.texture_for(irradiance, crate::texture::Lookup::Spectrum)?;
            // Mitsuba: the aspect ratio of the irradiance texture's resolution (1x1 for a
            // constant).
            let (w, h) = match &irradiance {
                crate::texture::Texture::Bitmap(b) => b.resolution(),
                _ => (1, 1),
            };
            let aspect = w as f64 / h as f64;
            Emitter::Projector(
                ProjectorEmitter::new(
                    shift * *to_world,
                    irradiance,
                    *scale,
                    fov_x_degrees(*fov, *fov_axis, aspect),
                    aspect,
                )
                .ok_or_else(|| Error::Invalid("to_world of a projector is degenerate".into()))?,
            )
        }
        EmitterDesc::Directional {
            direction,
            irradiance,
        } => Emitter::Directional(DirectionalEmitter {
            direction: direction.as_vec3(),
            irradiance: ColorValue::new(irradiance, textures.mode),
        }),
        EmitterDesc::Constant { radiance } => Emitter::Constant(ConstantEmitter {
            radiance: ColorValue::new(radiance, textures.mode),
        }),
        EmitterDesc::EnvMap {
            filename,
            scale,
            to_world,
            location,
        } => {
            let img = envmap_texels(filename)?;
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
            let new = match textures.mode {
                crate::spectrum::Mode::Rgb => EnvMapEmitter::new,
                crate::spectrum::Mode::Spectral => EnvMapEmitter::new_spectral,
            };
            Emitter::EnvMap(
                new(img.width, img.height, &img.rgb, *scale as f32, rot).ok_or_else(|| {
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
