//! Scene input and the built scene. Data flows one way: Mitsuba XML → [`xml`] (generic
//! object tree) → [`description`] (typed plain data) → [`build`] (render-ready [`Scene`]:
//! meshes, BVH, lights, materials).

pub mod build;
pub mod description;
pub mod resolver;
pub mod xml;

use crate::accel::Accel;
use crate::camera::Camera;
use crate::emitter::{DirectionSample, Emitter};
use crate::error::Result;
use crate::film::Filter;
use crate::geometry::{offset_ray_origin, Ray, SHADOW_EPSILON};
use crate::material::{Material, ShadingBsdf, ShadingContext};
use crate::shape::{Shape, SurfaceInteraction};
use crate::texture::TextureContext;
use glam::{Vec2, Vec3};
use std::path::Path;

/// A scene ready to render.
pub struct Scene {
    pub shapes: Vec<Shape>,
    /// The BSDFs of the shapes (and what they nest), with their textures.
    pub materials: Vec<Material>,
    pub emitters: Vec<Emitter>,
    /// The emitters' `sampling_weight`s as a distribution, when one is not 1 (else emitters
    /// are chosen uniformly, as Mitsuba does then).
    pub emitter_weights: Option<crate::sampling::Distribution1D>,
    pub accel: Accel,
    pub camera: Camera,
    /// The image: the film's crop window (by default the whole film).
    pub width: usize,
    pub height: usize,
    /// Where the image lies on the whole film (its crop offset) and the film's size, in
    /// pixels: samplers are keyed by film pixels, so a crop renders the same samples as the
    /// same pixels of the whole film.
    pub film_origin: (u32, u32),
    pub film_size: (u32, u32),
    /// Mitsuba's `sample_border`: pixels this far outside the image are sampled too, so that
    /// the pixels at the edges receive their filter's whole footprint (0 without it; the
    /// filter's border with it).
    pub sample_border: usize,
    pub filter: Filter,
    /// The sampler's `sample_count` after its rounding (the CLI's `--spp` overrides it).
    pub sample_count: u32,
    /// The sampler; its point count per pass is `sample_count` unless a render sets another
    /// ([`Scene::set_sample_count`]).
    pub sampler: crate::sampler::Sampler,
    /// The sampler's `seed`.
    pub seed: u64,
    /// The camera's world position: the scene is built around the camera (at the origin), so
    /// a world-space position is `p + world_origin`.
    pub world_origin: Vec3,
    /// Things the user should know that are not errors (skipped faces, no emitter, ...).
    pub warnings: Vec<String>,
    /// Index of the environment emitter (constant or envmap), at most one as in Mitsuba.
    pub environment: Option<u32>,
    /// Centre and radius of a sphere bounding every shape.
    pub bounding_sphere: (Vec3, f32),
    /// The participating media, referred to by index from shapes and the sensor.
    pub media: Vec<crate::medium::Medium>,
    /// The medium the sensor sits in (camera rays start in it).
    pub camera_medium: Option<u32>,
    /// Whether a shadow ray of the volumetric integrators can get past a surface or be
    /// attenuated on its way: the scene has media or a material with a null lobe (`null`,
    /// `mask`, `thindielectric`). Without, their shadow rays are plain occlusion tests.
    pub shadow_passthrough: bool,
    /// Per material, its [`ShadingBsdf`] built once when it is the same at every shading
    /// point ([`Material::is_uniform`]); see [`Scene::bsdf_at`].
    pub(crate) uniform_bsdfs: Vec<Option<ShadingBsdf>>,
}

impl Scene {
    /// The film pixel of image pixel (x, y), and the film's size: what a pixel's sample
    /// stream is keyed by ([`crate::sampler::Sampler::stream`]). With `sample_border` the
    /// pixels sampled outside the image (x or y down to −border) are keyed in the film
    /// enlarged by the border on every side.
    #[inline]
    pub fn sample_key(&self, x: i64, y: i64) -> ((u32, u32), (u32, u32)) {
        let b = self.sample_border as i64;
        (
            (
                (self.film_origin.0 as i64 + x + b) as u32,
                (self.film_origin.1 as i64 + y + b) as u32,
            ),
            (
                self.film_size.0 + 2 * b as u32,
                self.film_size.1 + 2 * b as u32,
            ),
        )
    }

    /// Makes the sampler draw passes of `spp` points, rounded as the plugin does (Mitsuba's
    /// `set_sample_count`, which its `render(spp=...)` calls); returns the rounded count and
    /// a warning when rounding changed it.
    pub fn set_sample_count(&mut self, spp: u32) -> (u32, Option<String>) {
        let (sampler, warning) = crate::sampler::Sampler::new(self.sampler.kind, spp);
        self.sampler = sampler;
        (sampler.sample_count, warning)
    }

    /// The typed description of a Mitsuba XML file (what [`build::build`] builds).
    pub fn load_description(
        path: &Path,
        defines: &[(String, String)],
    ) -> Result<description::SceneDescription> {
        description::from_xml(&xml::load_file(path, defines)?)
    }

    /// The typed description of XML text; `path` locates it for messages and relative files.
    pub fn description_from_xml_str(
        text: &str,
        path: &Path,
        defines: &[(String, String)],
    ) -> Result<description::SceneDescription> {
        description::from_xml(&xml::load_str(text, path, defines)?)
    }

    /// The closest surface hit by `ray`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let hit = self.accel.intersect(ray, &self.shapes)?;
        Some(self.accel.interaction(&hit, ray, &self.shapes))
    }

    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray, &self.shapes)
    }

    /// A ray leaving `si` in direction `d`, from an origin offset off the surface.
    #[inline]
    pub fn spawn_ray(si: &SurfaceInteraction, d: Vec3) -> Ray {
        Ray::new(
            offset_ray_origin(si.p, si.p_error, si.ng, d),
            d,
            f32::INFINITY,
        )
    }

    /// The shadow ray from `si` to the emitter point of `ds`. Towards a surface both ends are
    /// offset off their surfaces and the ray stops a relative [`SHADOW_EPSILON`] short of its
    /// end; towards a point light only the surface end is offset; towards an emitter at
    /// infinity the ray is unbounded.
    #[inline]
    pub fn shadow_ray(si: &SurfaceInteraction, ds: &DirectionSample) -> Ray {
        let from = offset_ray_origin(si.p, si.p_error, si.ng, ds.d);
        if ds.is_infinite() {
            return Ray::new(from, ds.d, f32::INFINITY);
        }
        let to = if ds.n == Vec3::ZERO {
            ds.p
        } else {
            offset_ray_origin(ds.p, ds.p_error, ds.n, -ds.d)
        };
        Self::ray_between(from, to)
    }

    /// The shadow ray from `from` to `to` (both already off their surfaces), stopping a
    /// relative [`SHADOW_EPSILON`] short of `to`.
    #[inline]
    pub fn ray_between(from: Vec3, to: Vec3) -> Ray {
        // Normalised: the BVH's slab test works with the inverse direction, and a tiny
        // unnormalised segment (a scene scaled by 1e-4) loses precision there.
        let v = to - from;
        let len = v.length();
        Ray::new(from, v / len, len * (1.0 - SHADOW_EPSILON))
    }

    /// The shadow ray between the surface points `a` and `b`, each end offset off its
    /// surface towards the other.
    #[inline]
    pub fn ray_between_surfaces(a: &SurfaceInteraction, b: &SurfaceInteraction) -> Ray {
        let d = b.p - a.p;
        Self::ray_between(
            offset_ray_origin(a.p, a.p_error, a.ng, d),
            offset_ray_origin(b.p, b.p_error, b.ng, -d),
        )
    }

    /// The shadow ray from a point `p` off any surface (a scattering event in a medium) to
    /// the emitter point of `ds`: as [`Scene::shadow_ray`] without the offset at `p`.
    #[inline]
    pub fn shadow_ray_from_point(p: Vec3, ds: &DirectionSample) -> Ray {
        if ds.is_infinite() {
            return Ray::new(p, ds.d, f32::INFINITY);
        }
        let to = if ds.n == Vec3::ZERO {
            ds.p
        } else {
            offset_ray_origin(ds.p, ds.p_error, ds.n, -ds.d)
        };
        let v = to - p;
        let len = v.length();
        Ray::new(p, v / len, len * (1.0 - SHADOW_EPSILON))
    }

    /// Whether the shape hit at `si` bounds a medium (has an interior or exterior one).
    #[inline]
    pub fn is_medium_transition(&self, si: &SurfaceInteraction) -> bool {
        let s = &self.shapes[si.shape as usize];
        s.interior.is_some() || s.exterior.is_some()
    }

    /// The medium a ray leaving `si` in direction `d` enters: the exterior one along the
    /// geometric normal, the interior one against it (Mitsuba's `target_medium`).
    #[inline]
    pub fn target_medium(&self, si: &SurfaceInteraction, d: Vec3) -> Option<u32> {
        let s = &self.shapes[si.shape as usize];
        if d.dot(si.ng) > 0.0 {
            s.exterior
        } else {
            s.interior
        }
    }

    /// The BSDF at surface interaction `si`, its textures looked up.
    #[inline]
    pub fn shading_bsdf(&self, si: &SurfaceInteraction) -> ShadingBsdf {
        let mut out = ShadingBsdf::new();
        self.shading_bsdf_into(si, &mut out);
        out
    }

    /// [`Scene::shading_bsdf`] written into `out` in place (the integrators' hot loops keep
    /// one per path instead of copying a new one out of each call).
    #[inline]
    pub fn shading_bsdf_into(&self, si: &SurfaceInteraction, out: &mut ShadingBsdf) {
        let shape = &self.shapes[si.shape as usize];
        let mesh = match &shape.geometry {
            crate::shape::ShapeGeometry::Mesh(m) => Some(m),
            _ => None,
        };
        let ctx = ShadingContext {
            tex: TextureContext {
                uv: si.uv,
                p: si.p,
                prim: si.prim,
                bary: si.bary,
                mesh,
            },
            frame: si.frame,
            dp_du: si.dp_du,
            dp_dv: si.dp_dv,
            ng: si.ng,
        };
        Material::shading_bsdf_into(&self.materials, shape.material, &ctx, out)
    }

    /// The BSDF at `si`: the material's prebuilt one when it does not vary over the surface
    /// ([`Material::is_uniform`]), else [`Scene::shading_bsdf_into`] filled into `buf`. The
    /// path integrators' hot loop: a material without textures costs no copy and no lookups
    /// per hit. Radiance transport only (the prebuilt BSDFs are not in importance mode).
    #[inline]
    pub fn bsdf_at<'a>(
        &'a self,
        si: &SurfaceInteraction,
        buf: &'a mut ShadingBsdf,
    ) -> &'a ShadingBsdf {
        let material = self.shapes[si.shape as usize].material as usize;
        if let Some(Some(bsdf)) = self.uniform_bsdfs.get(material) {
            return bsdf;
        }
        self.shading_bsdf_into(si, buf);
        buf
    }

    /// The prebuilt BSDFs of [`Scene::bsdf_at`], one per material (`None` where it varies).
    pub(crate) fn build_uniform_bsdfs(materials: &[Material]) -> Vec<Option<ShadingBsdf>> {
        let frame = crate::geometry::Frame::from_normal(Vec3::Z);
        let ctx = ShadingContext {
            tex: TextureContext::at_uv(Vec2::ZERO),
            frame,
            dp_du: frame.s,
            dp_dv: frame.t,
            ng: frame.n,
        };
        (0..materials.len() as u32)
            .map(|i| {
                Material::is_uniform(materials, i)
                    .then(|| Material::shading_bsdf(materials, i, &ctx))
            })
            .collect()
    }

    /// Probability of choosing emitter `i` for emitter sampling: uniform, as in Mitsuba,
    /// unless an emitter has a `sampling_weight` other than 1, then in proportion to the
    /// weights (Mitsuba's `Scene::pdf_emitter`). (Choosing in proportion to power was
    /// tried: on Mitsuba's regression scenes with an area light, an environment map and a
    /// point light it doubled the per-pixel variance of the env-lit pixels; see
    /// docs/performance.md.)
    #[inline]
    pub fn emitter_pmf(&self, i: usize) -> f32 {
        match &self.emitter_weights {
            None => 1.0 / self.emitters.len() as f32,
            Some(d) => d.pmf(i) as f32,
        }
    }

    /// Chooses an emitter for emitter sampling with `u` ∈ [0, 1) (Mitsuba's
    /// `Scene::sample_emitter`): its index, `u` rescaled to [0, 1) within the choice (so it
    /// serves again), and the probability of the choice. `None` without emitters.
    #[inline]
    pub fn pick_emitter(&self, u: f32) -> Option<(usize, f32, f32)> {
        let n = self.emitters.len();
        if n == 0 {
            return None;
        }
        if let Some(d) = &self.emitter_weights {
            let (i, r) = d.sample_reuse(u);
            return Some((i, r, d.pmf(i) as f32));
        }
        let x = u * n as f32;
        let i = (x as usize).min(n - 1);
        let r = (x - i as f32).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
        Some((i, r, 1.0 / n as f32))
    }

    /// Picks an emitter ([`Scene::pick_emitter`]) and a direction to it as seen from `si`;
    /// the returned pdf includes the selection probability. Visibility is not tested.
    pub fn sample_emitter_direction(
        &self,
        si: &SurfaceInteraction,
        u: Vec2,
    ) -> Option<DirectionSample> {
        self.sample_emitter_direction_at(si.p, u)
    }

    /// [`Scene::sample_emitter_direction`] from a point `p` that need not lie on a surface
    /// (a scattering event in a medium).
    pub fn sample_emitter_direction_at(&self, p: Vec3, u: Vec2) -> Option<DirectionSample> {
        self.sample_emitter_direction_indexed(p, u)
            .map(|(_, ds)| ds)
    }

    /// [`Scene::sample_emitter_direction_at`], with the index of the emitter chosen.
    pub fn sample_emitter_direction_indexed(
        &self,
        p: Vec3,
        u: Vec2,
    ) -> Option<(usize, DirectionSample)> {
        let (i, ux, pmf) = self.pick_emitter(u.x)?;
        let mut ds = self.emitters[i].sample_direction(p, Vec2::new(ux, u.y), &self.shapes)?;
        ds.pdf *= pmf;
        Some((i, ds))
    }

    /// The solid-angle density with which [`Scene::sample_emitter_direction`] from `p_ref`
    /// would have produced the emitter point `hit` (a surface with an area emitter).
    pub fn pdf_emitter_direction(&self, p_ref: Vec3, hit: &SurfaceInteraction) -> f32 {
        let Some(e) = self.shapes[hit.shape as usize].emitter else {
            return 0.0;
        };
        match &self.emitters[e as usize] {
            Emitter::Area(a) => {
                a.pdf_direction(p_ref, hit, &self.shapes) * self.emitter_pmf(e as usize)
            }
            _ => 0.0,
        }
    }

    /// Radiance of the environment emitter arriving along −`d` (0 without one).
    #[inline]
    pub fn eval_environment(&self, d: Vec3) -> Vec3 {
        match self.environment {
            Some(e) => self.emitters[e as usize].eval_environment(d.normalize()),
            None => Vec3::ZERO,
        }
    }

    /// The density with which [`Scene::sample_emitter_direction`] produces the escaping
    /// direction `d` (selection probability included).
    pub fn pdf_environment(&self, d: Vec3) -> f32 {
        match self.environment {
            Some(e) => {
                self.emitters[e as usize].pdf_environment(d.normalize())
                    * self.emitter_pmf(e as usize)
            }
            None => 0.0,
        }
    }
}
