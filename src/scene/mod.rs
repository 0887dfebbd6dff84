//! Scene input and the built scene. Data flows one way: Mitsuba XML → [`xml`] (generic
//! object tree) → [`description`] (typed plain data) → [`build`] (render-ready [`Scene`]:
//! meshes, BVH, lights, materials).

pub mod build;
pub mod description;
pub mod resolver;
pub mod xml;

use crate::accel::Accel;
use crate::camera::Camera;
use crate::emitter::{DirectionSample, DirectionSamples, Emitter};
use crate::error::Result;
use crate::film::Filter;
use crate::geometry::{offset_ray_origin, offset_ray_origin_lanes, Ray, Rays, SHADOW_EPSILON};
use crate::material::{Material, ShadingBsdf, ShadingContext};
use crate::shape::{Shape, SurfaceInteraction};
use crate::simd::{
    for_each_distinct, for_each_lane, LaneF32, LaneMask, LaneU32, Lanes, Scalar, V3,
};
use crate::spectrum::Spectrum;
use crate::texture::TextureContext;
use glam::{Vec2, Vec3, Vec4};
use std::path::Path;

/// A scene ready to render.
pub struct Scene {
    /// RGB or spectral: what the paths' [`Spectrum`] lanes hold.
    pub mode: crate::spectrum::Mode,
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
    /// infinity the ray is unbounded. The width-1 instance of [`Scene::shadow_ray_lanes`].
    #[inline]
    pub fn shadow_ray(si: &SurfaceInteraction, ds: &DirectionSample) -> Ray {
        let from = offset_ray_origin(si.p, si.p_error, si.ng, ds.d);
        Self::shadow_ray_from_lanes(Scalar, from.into(), &DirectionSamples::from(*ds)).into()
    }

    /// [`Scene::shadow_ray`] lane by lane, from the points `p` (error bounds `p_error`,
    /// geometric normals `ng`) to the emitter points of `ds`.
    #[inline(always)]
    pub fn shadow_ray_lanes<L: Lanes>(
        l: L,
        p: V3<L::F>,
        p_error: V3<L::F>,
        ng: V3<L::F>,
        ds: &DirectionSamples<L>,
    ) -> Rays<L> {
        let from = offset_ray_origin_lanes(l, p, p_error, ng, ds.d);
        Self::shadow_ray_from_lanes(l, from, ds)
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
        Self::shadow_ray_from_lanes(Scalar, p.into(), &DirectionSamples::from(*ds)).into()
    }

    /// The shadow ray from the (already offset) points `from` to the emitter points of `ds`,
    /// lane by lane: along `ds.d` without bound towards emitters at infinity; else to the
    /// emitter point, offset off its surface (not for point lights, whose normal is zero),
    /// normalised, and stopping a relative [`SHADOW_EPSILON`] short. (Normalised: the BVH's
    /// slab test works with the inverse direction, and a tiny unnormalised segment, in a
    /// scene scaled by 1e-4, loses precision there.)
    #[inline(always)]
    pub fn shadow_ray_from_lanes<L: Lanes>(
        l: L,
        from: V3<L::F>,
        ds: &DirectionSamples<L>,
    ) -> Rays<L> {
        let inf = l.splat(f32::INFINITY);
        let infinite = ds.is_infinite();
        let finite = !infinite;
        if !finite.any() {
            return Rays {
                o: from,
                d: ds.d,
                tmax: inf,
            };
        }
        let point = ds.n.cmp_eq(V3::splat(l.splat(0.0)));
        let to = if (finite & !point).any() {
            let off = offset_ray_origin_lanes(l, ds.p, ds.p_error, ds.n, -ds.d);
            V3::select(point, ds.p, off)
        } else {
            ds.p
        };
        let v = to - from;
        let len = v.length();
        Rays {
            o: from,
            d: V3::select(infinite, ds.d, v / len),
            tmax: L::F::select(infinite, inf, len * l.splat(1.0 - SHADOW_EPSILON)),
        }
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
    /// `wl`: the path's wavelengths (spectral mode; ignored in RGB mode).
    pub fn shading_bsdf(&self, si: &SurfaceInteraction, wl: Vec4) -> ShadingBsdf {
        let mut out = ShadingBsdf::new();
        self.shading_bsdf_into(si, wl, &mut out);
        out
    }

    /// [`Scene::shading_bsdf`] written into `out` in place (the integrators' hot loops keep
    /// one per path instead of copying a new one out of each call).
    #[inline]
    pub fn shading_bsdf_into(&self, si: &SurfaceInteraction, wl: Vec4, out: &mut ShadingBsdf) {
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
                wavelengths: wl,
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
        wl: Vec4,
        buf: &'a mut ShadingBsdf,
    ) -> &'a ShadingBsdf {
        let material = self.shapes[si.shape as usize].material as usize;
        if let Some(Some(bsdf)) = self.uniform_bsdfs.get(material) {
            return bsdf;
        }
        self.shading_bsdf_into(si, wl, buf);
        buf
    }

    /// The material of shape `shape`'s prebuilt BSDF, where it does not vary over the
    /// surface ([`Scene::bsdf_at`]).
    #[inline(always)]
    pub fn uniform_bsdf(&self, shape: u32) -> Option<&ShadingBsdf> {
        let material = self.shapes[shape as usize].material as usize;
        self.uniform_bsdfs.get(material)?.as_ref()
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
    /// serves again), and the probability of the choice. `None` without emitters. The
    /// width-1 instance of [`Scene::pick_emitter_lanes`].
    #[inline]
    pub fn pick_emitter(&self, u: f32) -> Option<(usize, f32, f32)> {
        let (ok, i, r, pmf) = self.pick_emitter_lanes(Scalar, true, u);
        ok.then_some((i as usize, r, pmf))
    }

    /// [`Scene::pick_emitter`] lane by lane where `m` is set: uniformly, x = u n, i =
    /// min(⌊x⌋, n − 1), u' = clamp(x − i, 0, 1 − ε/2), in lanes; by the `sampling_weight`s'
    /// distribution (an f64 CDF) lane by lane. No lane is picked without emitters.
    #[inline(always)]
    pub fn pick_emitter_lanes<L: Lanes>(
        &self,
        l: L,
        m: L::M,
        u: L::F,
    ) -> (L::M, L::U32, L::F, L::F) {
        let n = self.emitters.len();
        if n == 0 {
            let z = l.splat(0.0);
            return (l.mask(0), l.splat_u32(0), z, z);
        }
        if let Some(d) = &self.emitter_weights {
            let (mut idx, mut r, mut pmf) = (l.splat_u32(0), l.splat(0.0), l.splat(0.0));
            for_each_lane(
                L::WIDTH,
                m,
                #[inline(always)]
                |k| {
                    let (i, ri) = d.sample_reuse(u.lane(k));
                    idx.set_lane(k, i as u32);
                    r.set_lane(k, ri);
                    pmf.set_lane(k, d.pmf(i) as f32);
                },
            );
            return (m, idx, r, pmf);
        }
        let x = u * l.splat(n as f32);
        // (`x as usize` saturates; `as u32` gives the same below n − 1 < 2³²)
        let i = x.to_u32().min(l.splat_u32((n - 1) as u32));
        let r = (x - L::F::from_u32(i)).clamp(l.splat(0.0), l.splat(1.0 - f32::EPSILON / 2.0));
        (m, i, r, l.splat(1.0 / n as f32))
    }

    /// Picks an emitter ([`Scene::pick_emitter`]) and a direction to it as seen from `si`;
    /// the returned pdf includes the selection probability. Visibility is not tested.
    pub fn sample_emitter_direction(
        &self,
        si: &SurfaceInteraction,
        u: Vec2,
        wl: Vec4,
    ) -> Option<DirectionSample> {
        self.sample_emitter_direction_at(si.p, u, wl)
    }

    /// [`Scene::sample_emitter_direction`] from a point `p` that need not lie on a surface
    /// (a scattering event in a medium). The width-1 instance of
    /// [`Scene::sample_emitter_direction_lanes`].
    pub fn sample_emitter_direction_at(
        &self,
        p: Vec3,
        u: Vec2,
        wl: Vec4,
    ) -> Option<DirectionSample> {
        let (ok, ds) =
            self.sample_emitter_direction_lanes(Scalar, true, p.into(), (u.x, u.y), &[wl]);
        ok.then(|| ds.lane(0))
    }

    /// [`Scene::sample_emitter_direction_at`], with the index of the emitter chosen: the
    /// same arithmetic (the width-1 lanes), so that bdpt's next-event estimation draws what
    /// the path tracer's does, bit for bit.
    pub fn sample_emitter_direction_indexed(
        &self,
        p: Vec3,
        u: Vec2,
        wl: Vec4,
    ) -> Option<(usize, DirectionSample)> {
        let (ok, i, ux, pmf) = self.pick_emitter_lanes(Scalar, true, u.x);
        if !ok {
            return None;
        }
        let (ok, mut ds) = self.emitters[i as usize].sample_direction_lanes(
            Scalar,
            true,
            p.into(),
            (ux, u.y),
            &self.shapes,
            &[wl],
        );
        if !ok {
            return None;
        }
        ds.pdf *= pmf;
        Some((i as usize, ds.lane(0)))
    }

    /// [`Scene::sample_emitter_direction_at`] lane by lane where `m` is set: the emitter
    /// picked in lanes, then each emitter picked by some lane sampled for those lanes at
    /// once (a masked loop over the distinct emitters present, one pass in most scenes).
    /// The mask of the lanes that got a sample.
    #[inline(always)]
    pub fn sample_emitter_direction_lanes<L: Lanes>(
        &self,
        l: L,
        m: L::M,
        p: V3<L::F>,
        u: (L::F, L::F),
        wl: &[Vec4],
    ) -> (L::M, DirectionSamples<L>) {
        let (m, idx, ux, pmf) = self.pick_emitter_lanes(l, m, u.0);
        let mut out = DirectionSamples::zero(l);
        let mut ok = l.mask(0);
        let mut first = true;
        for_each_distinct(
            l,
            idx,
            m,
            #[inline(always)]
            |e, me| {
                let (oke, ds) = self.emitters[e as usize].sample_direction_lanes(
                    l,
                    me,
                    p,
                    (ux, u.1),
                    &self.shapes,
                    wl,
                );
                if first {
                    // (every lane but those of `me` is either outside `m` or taken by a later
                    // emitter: no merge needed, and none at all where one emitter serves all)
                    out = ds;
                    first = false;
                } else {
                    out = DirectionSamples::select(me, &ds, &out);
                }
                ok = ok | (oke & me);
            },
        );
        out.pdf = out.pdf * pmf;
        (ok, out)
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
    pub fn eval_environment(&self, d: Vec3, wl: Vec4) -> Spectrum {
        match self.environment {
            Some(e) => self.emitters[e as usize].eval_environment(d.normalize(), wl),
            None => Spectrum::ZERO,
        }
    }

    /// [`Scene::eval_environment`] and [`Scene::pdf_environment`] at once (one lookup of
    /// the direction in the map).
    #[inline]
    pub fn environment_with_pdf(&self, d: Vec3, wl: Vec4) -> (Spectrum, f32) {
        match self.environment {
            Some(e) => {
                let (le, pdf) =
                    self.emitters[e as usize].eval_environment_with_pdf(d.normalize(), wl);
                (le, pdf * self.emitter_pmf(e as usize))
            }
            None => (Spectrum::ZERO, 0.0),
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

#[cfg(test)]
mod tests {
    //! The emitter-sampling and shadow-ray lane kernels (issue 42, step 3a) against the
    //! scalar code of before, lane by lane, on every backend this processor runs.

    use super::*;
    use crate::simd::{dispatch, Backend, LaneProgram};
    use crate::spectrum::NO_WAVELENGTHS as NO_WL;
    use rand::{RngExt, SeedableRng};

    fn scene(weight: &str) -> Scene {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lanes-emitters.xml");
        let defines = [("weight".to_string(), weight.to_string())];
        crate::render::Job::load(&path, &defines)
            .expect("the test scene loads")
            .scene
    }

    /// `Scene::pick_emitter` as it was before the lane kernel.
    fn pick_reference(scene: &Scene, u: f32) -> Option<(usize, f32, f32)> {
        let n = scene.emitters.len();
        if n == 0 {
            return None;
        }
        if let Some(d) = &scene.emitter_weights {
            let (i, r) = d.sample_reuse(u);
            return Some((i, r, d.pmf(i) as f32));
        }
        let x = u * n as f32;
        let i = (x as usize).min(n - 1);
        let r = (x - i as f32).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
        Some((i, r, 1.0 / n as f32))
    }

    /// `Scene::sample_emitter_direction_at` as it was before the lane kernel: the pick, and
    /// for a constant area emitter on a mesh the point by area (`Mesh::sample_position`,
    /// checked against its own scalar code in `shape::mesh`) converted to solid angle.
    fn sample_reference(scene: &Scene, p_ref: Vec3, u: Vec2) -> Option<DirectionSample> {
        let (i, ux, pmf) = pick_reference(scene, u.x)?;
        let u = Vec2::new(ux, u.y);
        let mut ds = match &scene.emitters[i] {
            Emitter::Area(a) => match (&a.radiance, &scene.shapes[a.shape as usize].geometry) {
                (
                    crate::texture::Texture::Constant { rgb, .. },
                    crate::shape::ShapeGeometry::Mesh(m),
                ) => {
                    let ps = m.sample_position(u)?;
                    let v = ps.p - p_ref;
                    let dist2 = v.length_squared();
                    if dist2 == 0.0 || !dist2.is_finite() {
                        return None;
                    }
                    let dist = dist2.sqrt();
                    let d = v / dist;
                    let cos_light = ps.n.dot(-d);
                    if cos_light <= 0.0 {
                        return None;
                    }
                    let pdf = ps.pdf * dist2 / cos_light;
                    if !(pdf.is_finite() && pdf > 0.0) {
                        return None;
                    }
                    DirectionSample {
                        p: ps.p,
                        p_error: ps.p_error,
                        n: ps.n,
                        d,
                        dist,
                        pdf,
                        radiance: crate::spectrum::from_rgb(*rgb),
                        delta: false,
                    }
                }
                _ => scene.emitters[i].sample_direction(p_ref, u, &scene.shapes, NO_WL)?,
            },
            e => e.sample_direction(p_ref, u, &scene.shapes, NO_WL)?,
        };
        ds.pdf *= pmf;
        Some(ds)
    }

    /// `Scene::shadow_ray` as it was before the lane kernel (`offset_ray_origin` is checked
    /// against its own scalar code in `geometry`).
    fn shadow_reference(si: &SurfaceInteraction, ds: &DirectionSample) -> Ray {
        let from = offset_ray_origin(si.p, si.p_error, si.ng, ds.d);
        if ds.is_infinite() {
            return Ray::new(from, ds.d, f32::INFINITY);
        }
        let to = if ds.n == Vec3::ZERO {
            ds.p
        } else {
            offset_ray_origin(ds.p, ds.p_error, ds.n, -ds.d)
        };
        let v = to - from;
        let len = v.length();
        Ray::new(from, v / len, len * (1.0 - SHADOW_EPSILON))
    }

    struct Case {
        si: SurfaceInteraction,
        u: Vec2,
        active: bool,
    }

    /// Shading points on the scene's surfaces (hits of random rays, the emitters' own
    /// surfaces among them), random and edge sample values (0, the largest below 1, the
    /// uniform pick's boundaries k/5), some lanes inactive.
    fn cases(scene: &Scene, seed: u64) -> Vec<Case> {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(seed);
        let edges = [0.0, 1.0 - f32::EPSILON / 2.0, 0.2, 0.4, 0.6, 0.8, 0.5];
        let mut out = Vec::new();
        while out.len() < 16 * 400 {
            let o = Vec3::new(
                rng.random_range(-3.0f32..3.0),
                rng.random_range(0.01f32..4.0),
                rng.random_range(-2.9f32..6.0),
            );
            let d = Vec3::new(
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-1.0f32..1.0),
            );
            let Some(si) = scene.intersect(&Ray::new(o, d, f32::INFINITY)) else {
                continue;
            };
            let k = out.len();
            let u = match k % 4 {
                0 => Vec2::new(edges[k / 4 % 7], edges[k / 28 % 7]),
                _ => Vec2::new(rng.random::<f32>(), rng.random::<f32>()),
            };
            out.push(Case {
                si,
                u,
                active: rng.random_range(0..6) != 0,
            });
        }
        out
    }

    struct Sample<'a> {
        scene: &'a Scene,
        cases: &'a [Case],
    }

    impl LaneProgram for Sample<'_> {
        type Output = Vec<Option<(DirectionSample, Ray)>>;
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Self::Output {
            let mut out = Vec::new();
            for chunk in self.cases.chunks(L::WIDTH) {
                let mut geo = crate::shape::SurfaceInteractions::zero(l);
                let (mut u0, mut u1) = (l.splat(0.0), l.splat(0.0));
                let mut bits = 0;
                for (i, c) in chunk.iter().enumerate() {
                    geo.set_lane(i, &c.si);
                    u0.set_lane(i, c.u.x);
                    u1.set_lane(i, c.u.y);
                    bits |= (c.active as u32) << i;
                }
                let (ok, ds) = self.scene.sample_emitter_direction_lanes(
                    l,
                    l.mask(bits),
                    geo.p,
                    (u0, u1),
                    &[NO_WL; 16],
                );
                let ray = Scene::shadow_ray_lanes(l, geo.p, geo.p_error, geo.ng, &ds);
                out.extend(
                    (0..chunk.len())
                        .map(|i| (ok.bits() >> i & 1 != 0).then(|| (ds.lane(i), ray.lane(i)))),
                );
            }
            out
        }
    }

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    #[test]
    fn emitter_sampling_and_shadow_rays_in_lanes_match_the_scalar_code() {
        for weight in ["1", "3"] {
            let scene = scene(weight);
            assert_eq!(scene.emitters.len(), 5);
            assert_eq!(scene.emitter_weights.is_some(), weight != "1");
            let cases = cases(&scene, 0xe1 + weight.len() as u64);
            let want: Vec<Option<(DirectionSample, Ray)>> = cases
                .iter()
                .map(|c| {
                    let ds = sample_reference(&scene, c.si.p, c.u).filter(|_| c.active)?;
                    Some((ds, shadow_reference(&c.si, &ds)))
                })
                .collect();
            // every kind of emitter and both outcomes occur
            let got_some = want.iter().filter(|w| w.is_some()).count();
            assert!(got_some > 3000 && got_some < cases.len(), "{got_some}");
            for kind in [
                |ds: &DirectionSample| ds.delta,
                |ds: &DirectionSample| ds.is_infinite(),
                |ds: &DirectionSample| !ds.delta && !ds.is_infinite(),
            ] {
                assert!(want.iter().flatten().filter(|(ds, _)| kind(ds)).count() > 300);
            }
            for b in Backend::all_supported() {
                let got = dispatch(
                    b,
                    Sample {
                        scene: &scene,
                        cases: &cases,
                    },
                )
                .expect("supported");
                for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                    let key = |x: &Option<(DirectionSample, Ray)>| {
                        x.map(|(ds, r)| {
                            (
                                [
                                    ds.p,
                                    ds.p_error,
                                    ds.n,
                                    ds.d,
                                    crate::spectrum::to_rgb(ds.radiance),
                                    r.o,
                                    r.d,
                                ]
                                .map(bits),
                                [ds.dist, ds.pdf, r.tmax].map(f32::to_bits),
                                ds.delta,
                            )
                        })
                    };
                    assert_eq!(
                        key(g),
                        key(w),
                        "{b}, weight {weight}: case {k}, p {:?}, u {:?}",
                        cases[k].si.p,
                        cases[k].u
                    );
                }
            }
            // the scalar functions are the width-1 instances
            for (c, w) in cases.iter().zip(&want).filter(|(c, _)| c.active) {
                let g = scene
                    .sample_emitter_direction_at(c.si.p, c.u, NO_WL)
                    .map(|ds| (ds, Scene::shadow_ray(&c.si, &ds)));
                assert_eq!(format!("{g:?}"), format!("{w:?}"));
                assert_eq!(
                    scene.pick_emitter(c.u.x),
                    pick_reference(&scene, c.u.x),
                    "{:?}",
                    c.u
                );
            }
        }
    }
}
