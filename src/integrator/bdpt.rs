//! Bidirectional path tracing (`bdpt`, penumbra's own: Mitsuba 3 has none), as Veach 1997
//! (ch. 10) defines the estimator and pbrt-v4's `BDPTIntegrator` computes it: for every pixel
//! sample a camera subpath z₀ … z_{t−1} and a light subpath y₀ … y_{s−1}, both with Russian
//! roulette, and every connection of a prefix of one to a prefix of the other, weighted by
//! multiple importance sampling with the power heuristic over all the strategies (s, t) that
//! could have made the same path.
//!
//! The strategies, for a path of n = s + t vertices (n − 1 segments ≤ `max_depth`, counted as
//! Mitsuba's path tracer counts them, so that 1 shows the emitters seen directly and 2 adds
//! direct light):
//! - s = 0: the camera subpath ends on an emitter (an area light hit, or the environment when
//!   the ray escapes), as the path tracer's BSDF-sampled emission;
//! - s = 1: next-event estimation from camera vertex z_{t−1}: a point on an emitter is drawn
//!   afresh as the path tracer draws it ([`Scene::sample_emitter_direction`]), so `path` and
//!   `bdpt` share their estimators at s ≤ 1;
//! - t = 1: light vertex y_{s−1} connected to the camera through a lens point (light tracing,
//!   W_e / dist² as `ptracer` weighs it), splatted onto the film where it lands;
//! - s, t ≥ 2: the two subpaths' end vertices joined by a shadow ray.
//!
//! Paths of one segment are rendered by s = 0 alone (weight 1), as in pbrt-v4.
//!
//! **The path contribution every strategy estimates** is the path tracer's: a vertex x between
//! a camera-side neighbour c and a light-side neighbour l contributes the radiance-mode BSDF
//! value f(ω_xc, ω_xl) (with its cosine, the shading one towards l) times |n_g · ω_xc| (the
//! geometric cosine towards c, from the area measure). Camera subpaths sample it as the path
//! tracer does. Light subpaths evaluate the same value with the directions exchanged, divided
//! by the geometric cosine of the direction they arrived from (which the area measure of the
//! previous segment supplies): f(ω_xc, ω_xl) |n_g · ω_xc| / |n_g · ω_xl|. That is what a light
//! tracer's importance-mode BSDF times Veach's adjoint shading-normal correction (§5.3;
//! `ptracer`) computes wherever the BSDF is a proper adjoint; for Mitsuba's `normalmap` and
//! `bumpmap`, which are not (a light tracer and a path tracer render different images of
//! them, in Mitsuba too), it keeps bdpt on the path tracer's image. Only a Dirac-delta lobe
//! sampled by a light subpath takes the importance-mode weight and the adjoint correction
//! (no value to exchange directions in). A connection s, t ≥ 2 multiplies both vertices'
//! values and 1 / dist².
//!
//! **MIS weights.** w_s = p_s² / Σ_{s'} p_{s'}², each p_{s'} the density (in the area
//! product measure) with which strategy s' samples the path. As in pbrt-v4 the ratios
//! p_{s'} / p_s are built vertex by vertex from the densities each subpath stored while it
//! was traced (`pdf_fwd`, from its own side; `pdf_rev`, from the other side), with those at
//! the two connection vertices and their neighbours recomputed for the connection; no product
//! of densities is formed, so nothing underflows (the ratios are kept in f64). Densities
//! that a Dirac delta made (a specular lobe sampled at the vertex before) count as 1, and
//! strategies that would connect at such a vertex are left out. Two differences from pbrt-v4:
//! its weights use the balance heuristic, these the power heuristic; and the light's own
//! vertex y₀ has two densities, the one light subpaths draw it with (s ≥ 2: the emitter's
//! position sampling) and the one next-event estimation draws it with from z_{t−1} (s = 1:
//! for a sphere light seen from outside, the cone of directions it subtends; elsewhere the
//! same), so that at s ≤ 1 the weights are the path tracer's. A density the path cannot be
//! sampled with is 0, not remapped to 1 as pbrt-v4 does for every zero (that would give an
//! impossible strategy a share of the weight and lose it from the image). The weights are a
//! function of the path alone, so they sum to 1 over the strategies that can make it
//! (`tests::mis_weights_sum_to_one`), whatever densities the samplers actually used.
//!
//! Emitters at infinity (constant, envmap, directional) start light subpaths as
//! `Emitter::sample_ray` does, on a disk tangent to the scene's bounding sphere: their
//! vertex y₀ is a direction (density: the direction's, as next-event estimation draws it),
//! and y₁'s density is the disk's, 1/(π r²) per unit area across the ray. Delta lights
//! (point, spot, projector, directional) cannot be hit (no s = 0). Orthographic cameras
//! cannot be connected to (no t = 1); thin lenses can, through a lens point drawn uniformly.
//!
//! With `hide_emitters`, camera rays pass through area emitters before their first vertex
//! (as in `path`): light vertices on emitters are not connected to the camera, and the
//! connections to the camera pass through emitters too; paths of one segment are not drawn.
//!
//! **A share of light subpaths** (`light_paths`): a share c of the samples trace a light
//! subpath; the strategies s ≥ 2 are then weighted with Veach's MIS with sample counts (c
//! for them, 1 for s ≤ 1) and divided by c, so every c in (0, 1] gives the same expected
//! image. Left out (or 0), a pilot render chooses c ([`crate::render::choose_light_paths`]),
//! no smaller than [`LIGHT_SUBPATHS_PER_PIXEL`] / spp ([`Bdpt::resolved`]), or c = 0 where
//! every path has a camera-side strategy ([`Bdpt::camera_side_complete`]): then only the
//! strategies s ≤ 1 remain, which is the path tracer's estimator, and the path tracer
//! renders ([`Bdpt::path_tracer`]).
//!
//! Participating media are refused ([`super::ptracer::check_scene`]).
//!
//! Debugging (pbrt-v4 writes one image per strategy): the parameters `strategy_s` and
//! `strategy_t` render the contribution of that strategy alone, MIS-weighted (its share of the
//! full image; the images of all strategies add up to the full one) or, with `strategy_mis`
//! false, unweighted (its own estimate of all the light carried by paths of s + t vertices).

use super::path::PathIntegrator;
use super::ptracer::{adjoint_correction, ray_to_camera, sees_camera, Splat};
use super::{emission_at, pass_through_emitters, PathStats, MAX_SKIPPED_EMITTERS};
use crate::emitter::{DirectionSample, Emitter};
use crate::geometry::{Frame, Ray};
use crate::material::ShadingBsdf;
use crate::sampler::SampleStream;
use crate::scene::Scene;
use crate::shape::SurfaceInteraction;
use crate::spectrum::Spectrum;

use glam::{DVec2, Vec2, Vec3, Vec4};

/// The most vertices a subpath holds: an unbounded `max_depth` (−1) relies on Russian
/// roulette to end paths, which makes a subpath of this length about as likely as
/// 0.95^1000 ≈ 5e-23 with the default `rr_depth`.
/// The share of a pixel sample's unoccluded total below which a connection's shadow ray is
/// traced only with probability in proportion to what it carries (Russian roulette;
/// measured on the Cornell box: 17.5 → 12.0 rays per sample, per-sample variance +0.8%).
pub const SHADOW_RR: f32 = 0.1;
/// The light subpaths a pixel draws on average over a render at least, when the pilot
/// chooses their share: fewer make a pixel's estimate of the light side, divided by the
/// share, too heavy-tailed for its own variance to describe (measured: at 16 spp and a
/// share of 1/4, 1% of the Cornell box's pixel-channels fail Mitsuba's per-pixel test; at
/// 256 spp and 1/64 none beyond the rule's allowance).
pub const LIGHT_SUBPATHS_PER_PIXEL: f32 = 16.0;
pub const MAX_SUBPATH_VERTICES: usize = 1024;

#[derive(Clone, Debug)]
pub struct Bdpt {
    /// Longest path, in segments; `u32::MAX` for unbounded.
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Emitters seen directly are not shown (camera rays pass through area lights).
    pub hide_emitters: bool,
    /// Debugging: render only this strategy (s light vertices, t camera vertices).
    pub strategy: Option<(u32, u32)>,
    /// With `strategy`: weight its contribution by MIS (true) or not.
    pub strategy_mis: bool,
    /// The share of pixel samples that trace a light subpath (and so the strategies
    /// s ≥ 2); `None` (`light_paths` left out or 0): chosen for the scene by a pilot render
    /// ([`crate::render::choose_light_paths`]).
    pub light_paths: Option<f32>,
    /// The pilot's choices so far, by seed: renders of one integrator with one seed (the
    /// passes of a progressive render, the parts of one) run the pilot once.
    pub pilot_choices: std::sync::Arc<std::sync::Mutex<Vec<(u64, crate::render::LightPathChoice)>>>,
    /// Russian roulette on shadow rays ([`SHADOW_RR`]); off for the pilot, whose
    /// re-weighted contributions must not carry a roulette played with other weights.
    pub shadow_roulette: bool,
}

/// A connection's MIS weight and, for the pilot, the sums of the squared density ratios
/// (p_{s'} / p_s)² over the strategies s' ≤ 1 (`camera_side`) and s' ≥ 2 (`light_side`),
/// the strategy itself included: with a share c of samples tracing light subpaths, the
/// power heuristic's weight is c_s² / (camera_side + c² light_side), c_s = c for s ≥ 2.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mis {
    pub weight: f32,
    pub camera_side: f64,
    pub light_side: f64,
}

impl Mis {
    const ZERO: Mis = Mis {
        weight: 0.0,
        camera_side: 0.0,
        light_side: 0.0,
    };
    /// A strategy alone (the only one that makes its paths, or unweighted).
    const ALONE: Mis = Mis {
        weight: 1.0,
        camera_side: 1.0,
        light_side: 0.0,
    };
}

/// What a subpath vertex is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// The camera's lens point (the pinhole).
    Camera,
    /// A surface point with a BSDF (on an area emitter or not).
    Surface,
    /// A point on an area emitter that starts a light subpath or that next-event estimation
    /// drew.
    AreaLight,
    /// A point source: point, spot, projector.
    PointLight,
    /// An emitter at infinity (constant, envmap, directional), reached by a camera ray that
    /// left the scene, or starting a light subpath; `d` is the direction light travels.
    InfiniteLight,
}

/// Where a surface vertex's BSDF is.
#[derive(Clone, Copy, Debug)]
enum BsdfRef {
    None,
    /// The scene's prebuilt BSDF of this material (the same everywhere on the surface, and
    /// the same in both transport modes).
    Uniform(u32),
    /// The subpath's buffer slot.
    Own(u32),
}

/// A vertex of a camera or light subpath (pbrt-v4's `Vertex`).
#[derive(Clone, Copy, Debug)]
pub struct Vertex {
    kind: Kind,
    /// The point, its error bound and normals (for vertices off surfaces: `p` only; the
    /// normals of a light's own point are its emitting side's).
    si: SurfaceInteraction,
    /// Unit direction towards the previous vertex of its subpath (surfaces).
    wi: Vec3,
    /// Infinite lights: the unit direction light travels, into the scene.
    d: Vec3,
    /// The subpath's throughput arriving at this vertex (before it scatters).
    beta: Spectrum,
    /// The area density of this vertex sampled by its own subpath (solid angle for
    /// infinite lights), and by the other one (set once the next two vertices exist).
    pdf_fwd: f32,
    pdf_rev: f32,
    /// Light vertices: the density of being drawn as a light subpath's first vertex
    /// (emitter choice included).
    pdf_emit: f32,
    /// The vertex scattered through a Dirac delta (specular, or a null event).
    delta: bool,
    /// The emitter of a light vertex.
    emitter: u32,
    bsdf: BsdfRef,
}

/// A subpath and the BSDFs of its vertices that are not the scene's prebuilt ones.
#[derive(Clone, Default)]
pub struct Subpath {
    v: Vec<Vertex>,
    bsdfs: Vec<ShadingBsdf>,
    /// A light subpath's BSDF in importance mode, for the weight of a delta lobe sampled
    /// through a transmissive surface.
    importance: ShadingBsdf,
    /// The sample's wavelengths (spectral mode; both subpaths carry the same four).
    wl: Vec4,
}

/// The buffers of one worker: allocated once, reused for every sample.
#[derive(Clone, Default)]
pub struct Scratch {
    cam: Subpath,
    light: Subpath,
    /// This sample's connections, MIS-weighted, before their shadow rays.
    pending: Vec<(Candidate, Mis, usize, usize)>,
    /// The work done so far, by side (for the pilot's cost model).
    pub work: Work,
}

/// Work counts of the two sides of bidirectional samples: rays traced for the camera side
/// (its subpath and the strategies s ≤ 1) and for the light side (its subpath, the shadow
/// rays of s ≥ 2), and the connections s ≥ 2 evaluated.
#[derive(Clone, Copy, Debug, Default)]
pub struct Work {
    pub camera: u64,
    pub light: u64,
    pub connections: u64,
}

/// A surface record for a point off any surface (normal `n`, zero when none).
fn point_si(p: Vec3, n: Vec3) -> SurfaceInteraction {
    SurfaceInteraction {
        p,
        p_error: Vec3::ZERO,
        t: 0.0,
        ng: n,
        frame: Frame::from_normal(if n == Vec3::ZERO { Vec3::Z } else { n }),
        uv: Vec2::ZERO,
        dp_du: Vec3::ZERO,
        dp_dv: Vec3::ZERO,
        shape: u32::MAX,
        prim: 0,
        bary: Vec2::ZERO,
    }
}

impl Vertex {
    fn new(kind: Kind, si: SurfaceInteraction, beta: Spectrum) -> Self {
        Vertex {
            kind,
            si,
            wi: Vec3::ZERO,
            d: Vec3::ZERO,
            beta,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            pdf_emit: 0.0,
            delta: false,
            emitter: 0,
            bsdf: BsdfRef::None,
        }
    }

    fn camera(p: Vec3) -> Self {
        Self::new(Kind::Camera, point_si(p, Vec3::ZERO), Spectrum::ONE)
    }

    #[inline]
    fn p(&self) -> Vec3 {
        self.si.p
    }

    #[inline]
    fn on_surface(&self) -> bool {
        matches!(self.kind, Kind::Surface | Kind::AreaLight)
    }

    /// The unit direction from this vertex to `to` and the distance (∞ towards an infinite
    /// light); `None` when they coincide.
    #[inline]
    fn towards(&self, to: &Vertex) -> Option<(Vec3, f32)> {
        if to.kind == Kind::InfiniteLight {
            return Some((-to.d, f32::INFINITY));
        }
        let v = to.p() - self.p();
        let d2 = v.length_squared();
        (d2 > 0.0 && d2.is_finite()).then(|| {
            let d = d2.sqrt();
            (v / d, d)
        })
    }
}

/// The solid-angle density `pdf` of a direction from `from` towards `to`, as an area density
/// at `to` (pbrt-v4's `ConvertDensity`): unchanged towards an infinite light.
#[inline]
fn convert(from: Vec3, pdf: f32, to: &Vertex) -> f32 {
    if to.kind == Kind::InfiniteLight {
        return pdf;
    }
    let v = from - to.p();
    let d2 = v.length_squared();
    let apart = d2 > 0.0;
    if !apart {
        return 0.0;
    }
    let cos = if to.on_surface() {
        to.si.ng.dot(v).abs() / d2.sqrt()
    } else {
        1.0
    };
    pdf * cos / d2
}

impl Subpath {
    fn clear(&mut self) {
        self.v.clear();
    }

    /// The BSDF of vertex `i` (a surface).
    #[inline]
    fn bsdf<'a>(&'a self, scene: &'a Scene, i: usize) -> Option<&'a ShadingBsdf> {
        match self.v[i].bsdf {
            BsdfRef::None => None,
            BsdfRef::Uniform(m) => scene.uniform_bsdfs[m as usize].as_ref(),
            BsdfRef::Own(k) => self.bsdfs.get(k as usize),
        }
    }

    /// Looks up the BSDF of surface vertex `i` (radiance mode, in both subpaths).
    fn set_bsdf(&mut self, scene: &Scene, i: usize) {
        let si = self.v[i].si;
        let material = scene.shapes[si.shape as usize].material;
        if let Some(Some(_)) = scene.uniform_bsdfs.get(material as usize) {
            self.v[i].bsdf = BsdfRef::Uniform(material);
            return;
        }
        while self.bsdfs.len() <= i {
            self.bsdfs.push(ShadingBsdf::new());
        }
        scene.shading_bsdf_into(&si, self.wl, &mut self.bsdfs[i]);
        self.v[i].bsdf = BsdfRef::Own(i as u32);
    }

    /// Vertex `i`'s BSDF and its incoming direction in its shading frame, if it is a surface
    /// with a non-delta lobe there (a connection can only go through such a vertex).
    #[inline]
    fn connectible<'a>(&'a self, scene: &'a Scene, i: usize) -> Option<(&'a ShadingBsdf, Vec3)> {
        let v = &self.v[i];
        if v.kind != Kind::Surface {
            return None;
        }
        let bsdf = self.bsdf(scene, i)?;
        let wi = v.si.frame.to_local(v.wi);
        bsdf.has_smooth_lobe(wi).then_some((bsdf, wi))
    }
}

/// What light subpath vertex `v` (BSDF `bsdf`, light arriving from `v.wi`, `wi` in the
/// shading frame) sends towards the world direction `d` (`wo` in the shading frame): the
/// path tracer's value with the directions exchanged, f(d, wi) |n_g · d| / |n_g · wi| (see the
/// module's text).
#[inline]
fn light_value(v: &Vertex, bsdf: &ShadingBsdf, wi: Vec3, d: Vec3, wo: Vec3) -> Spectrum {
    let cos_in = v.si.ng.dot(v.wi).abs();
    if cos_in <= 0.0 {
        return Spectrum::ZERO;
    }
    bsdf.eval(wo, wi) * (v.si.ng.dot(d).abs() / cos_in)
}

/// The margin of film positions sampled beyond the window on each side (Mitsuba's
/// `sample_border`), in fractions of the window.
pub(crate) fn film_margin(scene: &Scene) -> DVec2 {
    let b = scene.sample_border as f64;
    DVec2::new(b / scene.width as f64, b / scene.height as f64)
}

/// The area emitter of a surface vertex (or of an area light vertex).
fn area_emitter<'a>(
    scene: &'a Scene,
    v: &Vertex,
) -> Option<(usize, &'a crate::emitter::AreaEmitter)> {
    let e = match v.kind {
        Kind::AreaLight => v.emitter as usize,
        Kind::Surface => scene.shapes[v.si.shape as usize].emitter? as usize,
        _ => return None,
    };
    match &scene.emitters[e] {
        Emitter::Area(a) => Some((e, a)),
        _ => None,
    }
}

/// The density with which light subpaths start at the light vertex `v` (a light vertex, or
/// a surface vertex on an area emitter that a camera subpath reached), emitter choice
/// included: area emitters by position, point sources 1 (a Dirac delta), the environment by
/// direction, a directional light 1.
fn pdf_emit(scene: &Scene, v: &Vertex) -> f32 {
    match v.kind {
        Kind::Surface => match area_emitter(scene, v) {
            Some((e, a)) => scene.emitter_pmf(e) * a.pdf_position(&v.si, &scene.shapes),
            None => 0.0,
        },
        _ => v.pdf_emit,
    }
}

/// The area density (solid angle for infinite lights) with which next-event estimation from
/// `from` draws the light vertex `v`, whose light-subpath density is `emit`: the same but
/// for a sphere light seen from outside, sampled by the cone it subtends.
fn pdf_nee(scene: &Scene, v: &Vertex, emit: f32, from: Vec3) -> f32 {
    if let Some((e, a)) = area_emitter(scene, v) {
        if let Some(cone) = a.cone_pdf(from, &scene.shapes) {
            return scene.emitter_pmf(e) * convert(from, cone, v);
        }
    }
    emit
}

/// The area density at `to` with which a light subpath leaving the light vertex `from`
/// reaches `to` (pbrt-v4's `PDFLight`).
fn pdf_light_direction(scene: &Scene, from: &Vertex, to: &Vertex) -> f32 {
    if from.kind == Kind::InfiniteLight {
        // The disk of the bounding sphere's radius, crossed by the rays.
        let r = scene.bounding_sphere.1;
        let planar = 1.0 / (std::f32::consts::PI * r * r);
        return if to.on_surface() {
            planar * to.si.ng.dot(from.d).abs()
        } else {
            planar
        };
    }
    let e = match from.kind {
        Kind::Surface => match area_emitter(scene, from) {
            Some((e, _)) => e,
            None => return 0.0,
        },
        _ => from.emitter as usize,
    };
    let Some((d, _)) = from.towards(to) else {
        return 0.0;
    };
    let pdf = scene.emitters[e].pdf_ray_direction(from.si.frame.n, d);
    convert(from.p(), pdf, to)
}

/// Whether a camera subpath can end on the light vertex `v` (s = 0): an area light or the
/// environment, not a Dirac delta.
fn hittable(scene: &Scene, v: &Vertex) -> bool {
    match v.kind {
        Kind::Surface | Kind::AreaLight => area_emitter(scene, v).is_some(),
        Kind::InfiniteLight => scene.emitters[v.emitter as usize].is_environment(),
        _ => false,
    }
}

/// The light vertex next-event estimation drew: emitter `e`, sample `ds`.
fn light_vertex_from_sample(scene: &Scene, e: usize, ds: &DirectionSample) -> Vertex {
    let pmf = scene.emitter_pmf(e);
    let emitter = &scene.emitters[e];
    let mut v = if ds.is_infinite() {
        let mut v = Vertex::new(
            Kind::InfiniteLight,
            point_si(Vec3::ZERO, Vec3::ZERO),
            Spectrum::ONE,
        );
        v.d = -ds.d;
        v.pdf_emit = if emitter.is_environment() {
            scene.pdf_environment(ds.d)
        } else {
            pmf
        };
        v
    } else if let Emitter::Area(a) = emitter {
        let mut si = point_si(ds.p, ds.n);
        si.p_error = ds.p_error;
        let mut v = Vertex::new(Kind::AreaLight, si, Spectrum::ONE);
        // The emitter's position density: uniform by area for a constant radiance; the
        // texture's, p_ω |cos| / dist², for a textured one.
        v.pdf_emit = if !a.radiance.is_spatially_varying() {
            pmf * (1.0 / scene.shapes[a.shape as usize].geometry.area()) as f32
        } else {
            ds.pdf * ds.n.dot(ds.d).abs() / (ds.dist * ds.dist)
        };
        v
    } else {
        let mut v = Vertex::new(Kind::PointLight, point_si(ds.p, Vec3::ZERO), Spectrum::ONE);
        v.pdf_emit = pmf;
        v
    };
    v.emitter = e as u32;
    v.pdf_fwd = v.pdf_emit;
    v
}

/// What a connection must test before it counts.
#[derive(Clone)]
enum Shadow {
    /// Nothing (s = 0: the camera subpath reached the emitter).
    None,
    Ray(Ray),
    /// From the light vertex's surface to the lens point (t = 1).
    Camera(Vec3),
}

/// A strategy's unweighted, unoccluded contribution.
#[derive(Clone)]
struct Candidate {
    value: Spectrum,
    /// The vertex drawn for it: the light point (s = 1) or the lens point (t = 1).
    sampled: Option<Vertex>,
    /// Where a t = 1 contribution lands on the film (window fractions).
    film: Option<Vec2>,
    shadow: Shadow,
}

/// One connection's record, for tests: the subpaths, the vertex drawn for it (s = 1, t = 1)
/// and its MIS weight.
#[cfg_attr(not(test), allow(dead_code))]
pub(crate) struct Connection<'a> {
    pub cam: &'a Subpath,
    pub light: &'a Subpath,
    pub sampled: Option<Vertex>,
    pub s: usize,
    pub t: usize,
    pub weight: f32,
    /// The unweighted contribution, the probability its shadow ray was traced with (shadow
    /// roulette) and the MIS sums.
    pub value: Spectrum,
    pub kept: f32,
    pub mis: Mis,
}

impl Bdpt {
    /// The share of samples that trace a light subpath, as this integrator renders (1 until
    /// a pilot has chosen one).
    pub fn light_share(&self) -> f32 {
        self.light_paths.unwrap_or(1.0)
    }

    /// This integrator with its share of light subpaths chosen for `scene` by the pilot
    /// render ([`crate::render::choose_light_paths`]) where the scene leaves it open, for a
    /// render of `spp` samples per pixel in all (its parts and resumptions included): at
    /// least [`LIGHT_SUBPATHS_PER_PIXEL`] / `spp`, so that every pixel draws that many light
    /// subpaths on average.
    pub fn resolved(&self, scene: &Scene, seed: u64, spp: u64, pool: &rayon::ThreadPool) -> Bdpt {
        let mut b = self.clone();
        if b.strategy.is_some() {
            // A strategy alone is a debugging image: every sample traces both subpaths,
            // unless told otherwise.
            b.light_paths = Some(b.light_share());
        }
        if b.light_paths.is_none() {
            let floor = LIGHT_SUBPATHS_PER_PIXEL / spp.max(1) as f32;
            if floor >= 1.0 {
                b.light_paths = Some(1.0);
                return b;
            }
            let known = self
                .pilot_choices
                .lock()
                .ok()
                .and_then(|c| c.iter().find(|(s, _)| *s == seed).map(|(_, x)| x.clone()));
            let choice = known.unwrap_or_else(|| {
                let choice = crate::render::choose_light_paths(scene, self, seed, pool);
                if let Ok(mut c) = self.pilot_choices.lock() {
                    c.push((seed, choice.clone()));
                }
                choice
            });
            b.light_paths = Some(choice.best(floor));
        }
        b
    }

    /// Whether every path of `scene` that carries light has a strategy s ≤ 1 (the camera
    /// subpath meets an emitter, or next-event estimation draws it), so that the estimator
    /// without light subpaths (share 0) is unbiased too: true when no emitter is a Dirac
    /// delta (point, spot, projector, directional). A delta light cannot be met by a camera
    /// subpath, and where the vertex next to it scatters through a delta lobe (a point light
    /// seen through glass) next-event estimation cannot draw it either; only light subpaths
    /// make those paths. Area emitters and emitters at infinity are met by camera subpaths,
    /// which sample every direction their BSDFs scatter to.
    pub fn camera_side_complete(&self, scene: &Scene) -> bool {
        self.strategy.is_none() && !scene.emitters.iter().any(Emitter::is_delta)
    }

    /// The estimator without light subpaths (share 0): the strategies s ≤ 1, weighted by
    /// the power heuristic between them, are the path tracer's (a camera path meeting an
    /// emitter, and next-event estimation, with the same roulette and depth), so a share of
    /// 0 renders with [`PathIntegrator`] itself.
    pub fn path_tracer(&self) -> PathIntegrator {
        PathIntegrator {
            max_depth: self.max_depth,
            rr_depth: self.rr_depth,
            hide_emitters: self.hide_emitters,
        }
    }

    /// Longest subpaths: camera max_depth + 1 vertices (s = 0), light max_depth (t = 1).
    fn max_camera_vertices(&self) -> usize {
        (self.max_depth as usize)
            .saturating_add(1)
            .min(MAX_SUBPATH_VERTICES)
    }

    fn max_light_vertices(&self) -> usize {
        (self.max_depth as usize).min(MAX_SUBPATH_VERTICES)
    }

    /// One pixel sample: the camera subpath along `ray`, a light subpath, and every
    /// connection. Returns the radiance of the strategies t ≥ 2 (for this sample's film
    /// position) and pushes those of t = 1 to `splats` (weight 1 each: the caller divides by
    /// the samples per pixel).
    ///
    /// `wl` are the sample's wavelengths in spectral mode ([`crate::spectrum::NO_WAVELENGTHS`] in RGB mode):
    /// both subpaths and every connection are evaluated at them, and the caller converts the
    /// radiance and the splats with their weights.
    #[allow(clippy::too_many_arguments)]
    pub fn sample(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        scratch: &mut Scratch,
        stats: &mut PathStats,
        splats: &mut Vec<Splat>,
    ) -> Spectrum {
        self.sample_recorded(scene, ray, wl, sampler, scratch, stats, splats, &mut |_| {})
    }

    #[allow(clippy::too_many_arguments)]
    pub(crate) fn sample_recorded(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        scratch: &mut Scratch,
        stats: &mut PathStats,
        splats: &mut Vec<Splat>,
        record: &mut dyn FnMut(&Connection),
    ) -> Spectrum {
        if self.max_depth == 0 {
            return Spectrum::ZERO;
        }
        let margin = film_margin(scene);
        scratch.cam.wl = wl;
        scratch.light.wl = wl;
        let rays = stats.rays;
        self.camera_subpath(scene, ray, margin, sampler, &mut scratch.cam, stats);
        scratch.work.camera += stats.rays - rays;
        let share = self.light_share();
        // A share of the samples trace a light subpath; the others make only the strategies
        // s ≤ 1 (the MIS weights count the strategies s ≥ 2 with that share, and their
        // contributions are divided by it).
        let traced = share >= 1.0 || sampler.next_1d() < share;
        let rays = stats.rays;
        if traced {
            self.light_subpath(scene, sampler, &mut scratch.light, stats);
        } else {
            scratch.light.clear();
        }
        scratch.work.light += stats.rays - rays;
        let (cam, light) = (&scratch.cam, &scratch.light);
        let mut l = Spectrum::ZERO;
        let pending = &mut scratch.pending;
        pending.clear();
        for t in 1..=cam.v.len() {
            for s in 0..=light.v.len().max(1) {
                let n = s + t;
                if n < 2 || (s == 1 && t == 1) || (n - 1) as u64 > self.max_depth as u64 {
                    continue;
                }
                if self.hide_emitters && n == 2 {
                    continue;
                }
                let Some(c) = self.connect(scene, cam, light, s, t, margin, sampler) else {
                    continue;
                };
                let mis = if self.strategy.is_some() && !self.strategy_mis {
                    Mis::ALONE
                } else {
                    self.mis(scene, cam, light, c.sampled.as_ref(), s, t, margin)
                };
                if s >= 2 {
                    scratch.work.connections += 1;
                }
                if mis.weight > 0.0 {
                    pending.push((c, mis, s, t));
                }
            }
        }
        // Russian roulette on the shadow rays (Veach 1997, §10.3.4's efficiency-minded
        // roulette of visibility tests): a connection that carries less than a share
        // `SHADOW_RR` of this sample's unoccluded total is tested with probability
        // proportional to what it carries and weighted by the inverse.
        let inv_share = 1.0 / share;
        let scaled = |c: &Candidate, w: f32, s: usize| {
            let v = c.value * w;
            if s >= 2 {
                v * inv_share
            } else {
                v
            }
        };
        let total: f32 = pending
            .iter()
            .map(|(c, mis, s, _)| scaled(c, mis.weight, *s).max_element())
            .sum();
        let threshold = if self.shadow_roulette {
            SHADOW_RR * total
        } else {
            0.0
        };
        for (c, mis, s, t) in pending.iter() {
            let (s, t) = (*s, *t);
            let mut value = scaled(c, mis.weight, s);
            let mut kept = 1.0;
            if !matches!(c.shadow, Shadow::None) && threshold > 0.0 {
                let q = (value.max_element() / threshold).min(1.0);
                if q < 1.0 {
                    if sampler.next_1d() >= q {
                        continue;
                    }
                    value /= q;
                    kept = q;
                }
            }
            let wanted = self.strategy.is_none_or(|st| st == (s as u32, t as u32));
            let rays = stats.rays;
            let visible = wanted && self.visible(scene, light, s, &c.shadow, stats);
            if s >= 2 {
                scratch.work.light += stats.rays - rays;
            } else {
                scratch.work.camera += stats.rays - rays;
            }
            if !visible {
                continue;
            }
            record(&Connection {
                cam,
                light,
                sampled: c.sampled,
                s,
                t,
                weight: mis.weight,
                value: c.value,
                kept,
                mis: *mis,
            });
            match c.film {
                Some(film) => splats.push(Splat { film, value }),
                None => l += value,
            }
        }
        l
    }

    /// The unweighted, unoccluded contribution of strategy (s, t), the vertex it drew (the
    /// light point for s = 1, the lens point for t = 1) and, for t = 1, the film position;
    /// `None` when it carries nothing.
    #[allow(clippy::too_many_arguments)]
    fn connect(
        &self,
        scene: &Scene,
        cam: &Subpath,
        light: &Subpath,
        s: usize,
        t: usize,
        margin: DVec2,
        sampler: &mut SampleStream,
    ) -> Option<Candidate> {
        let positive = |v: Spectrum| (v.max_element() > 0.0).then_some(v);
        if s == 0 {
            // The camera subpath ends on an emitter.
            let pt = &cam.v[t - 1];
            let le = match pt.kind {
                Kind::Surface => emission_at(scene, Some(&pt.si), -pt.wi, cam.wl),
                Kind::InfiniteLight => scene.eval_environment(-pt.d, cam.wl),
                _ => Spectrum::ZERO,
            };
            return Some(Candidate {
                value: positive(pt.beta * le)?,
                sampled: None,
                film: None,
                shadow: Shadow::None,
            });
        }
        if t == 1 {
            // Light tracing: the light vertex seen by the camera.
            let qs = &light.v[s - 1];
            let (bsdf, wi) = light.connectible(scene, s - 1)?;
            if self.hide_emitters && scene.shapes[qs.si.shape as usize].emitter.is_some() {
                return None; // camera rays pass through emitters
            }
            let u = if scene.camera.needs_aperture_sample() {
                sampler.next_2d()
            } else {
                Vec2::ZERO
            };
            let c = scene.camera.connect(qs.p(), u, margin)?;
            let f = light_value(qs, bsdf, wi, c.d, qs.si.frame.to_local(c.d));
            let value = positive(qs.beta * f * c.weight)?;
            return Some(Candidate {
                value,
                sampled: Some(Vertex::camera(c.p)),
                film: Some(c.film),
                shadow: Shadow::Camera(c.p),
            });
        }
        if s == 1 {
            // Next-event estimation, as the path tracer does it.
            let pt = &cam.v[t - 1];
            let (bsdf, wi) = cam.connectible(scene, t - 1)?;
            let u = sampler.next_2d();
            let (e, ds) = scene.sample_emitter_direction_indexed(pt.p(), u, cam.wl)?;
            let f = bsdf.eval(wi, pt.si.frame.to_local(ds.d));
            let value = positive(pt.beta * f * ds.radiance / ds.pdf)?;
            return Some(Candidate {
                value,
                sampled: Some(light_vertex_from_sample(scene, e, &ds)),
                film: None,
                shadow: Shadow::Ray(Scene::shadow_ray(&pt.si, &ds)),
            });
        }
        // Both subpaths end on surfaces: join them.
        let (pt, qs) = (&cam.v[t - 1], &light.v[s - 1]);
        let (bsdf_p, wi_p) = cam.connectible(scene, t - 1)?;
        let (bsdf_q, wi_q) = light.connectible(scene, s - 1)?;
        let (d, dist) = pt.towards(qs)?;
        let f_p = bsdf_p.eval(wi_p, pt.si.frame.to_local(d));
        if f_p.max_element() <= 0.0 {
            return None;
        }
        let f_q = light_value(qs, bsdf_q, wi_q, -d, qs.si.frame.to_local(-d));
        let value = pt.beta * f_p * f_q * qs.beta / (dist * dist);
        Some(Candidate {
            value: positive(value)?,
            sampled: None,
            film: None,
            shadow: Shadow::Ray(Scene::ray_between_surfaces(&pt.si, &qs.si)),
        })
    }

    /// Whether connection (s, t) is unoccluded.
    fn visible(
        &self,
        scene: &Scene,
        light: &Subpath,
        s: usize,
        shadow: &Shadow,
        stats: &mut PathStats,
    ) -> bool {
        match shadow {
            Shadow::None => true,
            Shadow::Ray(ray) => {
                stats.rays += 1;
                !scene.occluded(ray)
            }
            Shadow::Camera(lens) => {
                stats.rays += 1;
                let qs = &light.v[s - 1].si;
                if self.hide_emitters {
                    sees_camera_past_emitters(scene, qs, *lens, stats)
                } else {
                    sees_camera(scene, qs, *lens)
                }
            }
        }
    }

    /// Traces the camera subpath: the lens point, then the surfaces the ray meets (passing
    /// through emitters first with `hide_emitters`) and the environment where it escapes.
    fn camera_subpath(
        &self,
        scene: &Scene,
        mut ray: Ray,
        margin: DVec2,
        sampler: &mut SampleStream,
        cam: &mut Subpath,
        stats: &mut PathStats,
    ) {
        cam.clear();
        let mut x0 = Vertex::camera(scene.camera.lens_point(&ray));
        // An orthographic camera's direction is a Dirac delta: no connection to it.
        x0.delta = !scene.camera.connects();
        cam.v.push(x0);
        let max_vertices = self.max_camera_vertices();
        let mut beta = Spectrum::ONE;
        let mut eta = 1.0f32;
        let mut pdf_dir = scene.camera.pdf_direction(ray.d, margin);
        loop {
            stats.rays += 1;
            let mut hit = scene.intersect(&ray);
            let first = cam.v.len() == 1;
            if first && self.hide_emitters {
                hit = pass_through_emitters(scene, ray.d, hit, stats);
            }
            let prev = cam.v.len() - 1;
            let wi = -ray.d.normalize();
            let Some(si) = hit else {
                if let Some(env) = scene.environment {
                    if !(first && self.hide_emitters) {
                        let mut v = Vertex::new(
                            Kind::InfiniteLight,
                            point_si(Vec3::ZERO, Vec3::ZERO),
                            beta,
                        );
                        v.d = wi;
                        v.emitter = env;
                        v.pdf_fwd = pdf_dir;
                        v.pdf_emit = scene.pdf_environment(-wi);
                        cam.v.push(v);
                    }
                }
                break;
            };
            let mut v = Vertex::new(Kind::Surface, si, beta);
            v.wi = wi;
            v.pdf_fwd = convert(cam.v[prev].p(), pdf_dir, &v);
            cam.v.push(v);
            let i = cam.v.len() - 1;
            // The last vertex too: connections go through its BSDF.
            cam.set_bsdf(scene, i);
            if cam.v.len() >= max_vertices {
                break;
            }
            stats.bounces += 1;
            let Some(bsdf) = cam.bsdf(scene, i) else {
                break;
            };
            let wi_local = si.frame.to_local(wi);
            let u1 = sampler.next_1d();
            let u2 = sampler.next_2d();
            let Some(bs) = bsdf.sample(wi_local, u1, u2) else {
                break;
            };
            let wo_world = si.frame.to_world(bs.wo);
            let (pdf_fwd, pdf_rev) = if bs.delta {
                (0.0, 0.0)
            } else {
                (bs.pdf, bsdf.pdf(bs.wo, wi_local))
            };
            cam.v[i].delta = bs.delta;
            if prev > 0 {
                let p = cam.v[i].p();
                cam.v[prev].pdf_rev = convert(p, pdf_rev, &cam.v[prev]);
            }
            beta *= bs.weight;
            eta *= bs.eta;
            pdf_dir = pdf_fwd;
            ray = Scene::spawn_ray(&si, wo_world);
            // Russian roulette, as the path tracer plays it.
            let bounces = i as u32;
            let beta_max = beta.max_element();
            if beta_max <= 0.0 || !beta_max.is_finite() {
                break;
            }
            if bounces >= self.rr_depth {
                let q = (beta_max * eta * eta).min(0.95);
                if sampler.next_1d() >= q {
                    stats.rr_terminated += 1;
                    break;
                }
                beta /= q;
            }
        }
    }

    /// Traces the light subpath: a ray from an emitter picked as next-event estimation
    /// picks them, as `ptracer` draws it, then the surfaces it meets, in importance mode.
    fn light_subpath(
        &self,
        scene: &Scene,
        sampler: &mut SampleStream,
        light: &mut Subpath,
        stats: &mut PathStats,
    ) {
        light.clear();
        let max_vertices = self.max_light_vertices();
        if max_vertices == 0 {
            return;
        }
        let Some((e, _, pmf)) = scene.pick_emitter(sampler.next_1d()) else {
            return;
        };
        let u_dir = sampler.next_2d();
        let u_pos = sampler.next_2d();
        let emitter = &scene.emitters[e];
        let Some(er) =
            emitter.sample_ray(u_pos, u_dir, &scene.shapes, scene.bounding_sphere, light.wl)
        else {
            return;
        };
        let d = er.ray.d;
        let mut y0 = if emitter.is_infinite() {
            let mut v = Vertex::new(
                Kind::InfiniteLight,
                point_si(Vec3::ZERO, Vec3::ZERO),
                Spectrum::ONE,
            );
            v.d = d;
            v.pdf_emit = if emitter.is_environment() {
                scene.pdf_environment(-d)
            } else {
                pmf
            };
            v
        } else if matches!(emitter, Emitter::Area(_)) {
            let mut si = point_si(er.origin, er.ng);
            si.frame = Frame::from_normal(er.n);
            let mut v = Vertex::new(Kind::AreaLight, si, Spectrum::ONE);
            v.pdf_emit = pmf * er.pdf_pos;
            v
        } else {
            let mut v = Vertex::new(
                Kind::PointLight,
                point_si(er.origin, Vec3::ZERO),
                Spectrum::ONE,
            );
            v.pdf_emit = pmf;
            v
        };
        y0.emitter = e as u32;
        y0.pdf_fwd = y0.pdf_emit;
        light.v.push(y0);
        let mut beta = er.weight / pmf;
        // Russian roulette weighs the throughput relative to the emitter's: a light
        // subpath's throughput carries the emitted power, not a fraction of 1.
        let beta_scale = 1.0 / beta.max_element();
        let mut eta = 1.0f32;
        let mut ray = er.ray;
        // The density of the next vertex: the emitter's direction density (for infinite
        // lights, the disk's, applied below).
        let mut pdf_dir = emitter.pdf_ray_direction(er.n, d);
        while light.v.len() < max_vertices {
            stats.rays += 1;
            let Some(si) = scene.intersect(&ray) else {
                break;
            };
            let prev = light.v.len() - 1;
            let wi = -ray.d.normalize();
            let mut v = Vertex::new(Kind::Surface, si, beta);
            v.wi = wi;
            v.pdf_fwd = if prev == 0 {
                pdf_light_direction(scene, &light.v[0], &v)
            } else {
                convert(light.v[prev].p(), pdf_dir, &v)
            };
            light.v.push(v);
            let i = light.v.len() - 1;
            light.set_bsdf(scene, i);
            if light.v.len() >= max_vertices {
                break;
            }
            stats.bounces += 1;
            let Some(bsdf) = light.bsdf(scene, i) else {
                break;
            };
            let wi_local = si.frame.to_local(wi);
            let u1 = sampler.next_1d();
            let u2 = sampler.next_2d();
            let Some(bs) = bsdf.sample(wi_local, u1, u2) else {
                break;
            };
            let wo_world = si.frame.to_world(bs.wo);
            // The throughput's factor: the value light_value gives (see the module's text)
            // over the density, or for a delta lobe its importance-mode weight (refraction:
            // without radiance's 1/η²) with the adjoint correction.
            let (weight, pdf_fwd, pdf_rev) = if bs.delta {
                let transmissive = bsdf.is_transmissive();
                let Some(correction) = adjoint_correction(si.ng, wi, wi_local, wo_world, bs.wo)
                else {
                    break;
                };
                let weight = if transmissive {
                    // The same lobe and direction (importance mode changes weights only).
                    scene.shading_bsdf_into(&si, light.wl, &mut light.importance);
                    light.importance.set_importance();
                    match light.importance.sample(wi_local, u1, u2) {
                        Some(b) => b.weight,
                        None => break,
                    }
                } else {
                    bs.weight
                };
                (weight * correction, 0.0, 0.0)
            } else {
                let f = light_value(&light.v[i], bsdf, wi_local, wo_world, bs.wo);
                (f / bs.pdf, bs.pdf, bsdf.pdf(bs.wo, wi_local))
            };
            light.v[i].delta = bs.delta;
            let p = light.v[i].p();
            light.v[prev].pdf_rev = convert(p, pdf_rev, &light.v[prev]);
            beta *= weight;
            eta *= bs.eta;
            pdf_dir = pdf_fwd;
            if !beta.is_finite() || beta.max_element() <= 0.0 {
                break;
            }
            // Russian roulette, as the camera subpath plays it, on the throughput relative
            // to the emitted one.
            let bounces = i as u32;
            if bounces >= self.rr_depth {
                let q = (beta.max_element() * beta_scale * eta * eta).min(0.95);
                if sampler.next_1d() >= q {
                    // Not counted in `rr_terminated`: that statistic is the fraction of
                    // samples whose camera subpath roulette ended, as `path` reports it.
                    break;
                }
                beta /= q;
            }
            ray = Scene::spawn_ray(&si, wo_world);
        }
    }

    /// The power-heuristic MIS weight of strategy (s, t) for the path it made (camera
    /// vertices `cam[..t]`, the lens point `sampled` for t = 1; light vertices `light[..s]`,
    /// the light point `sampled` for s = 1), and the sums of squared density ratios the pilot
    /// needs ([`Mis`]). The weight counts the strategies s' ≥ 2, which use the light subpath,
    /// with the share of samples that trace one ([`Self::light_share`]): w_s = (c_s p_s)² /
    /// Σ_{s'} (c_{s'} p_{s'})², c = 1 for s' ≤ 1 (Veach's MIS with sample counts).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn mis(
        &self,
        scene: &Scene,
        cam: &Subpath,
        light: &Subpath,
        sampled: Option<&Vertex>,
        s: usize,
        t: usize,
        margin: DVec2,
    ) -> Mis {
        let zero = Mis::ZERO;
        let n = s + t;
        if n == 2 {
            return Mis::ALONE;
        }
        // Vertex j of the path, from the camera (0) to the light (n − 1): for t = 1 the lens
        // point and for s = 1 the light point drawn for the connection (the light subpath may
        // be empty then).
        let drawn = sampled.filter(|_| s == 1 || t == 1);
        if (s == 1 || t == 1) && drawn.is_none() {
            return zero;
        }
        let vert = |j: usize| -> &Vertex {
            if j < t {
                match drawn {
                    Some(v) if j == 0 && t == 1 => v,
                    _ => &cam.v[j],
                }
            } else {
                let k = n - 1 - j;
                match drawn {
                    Some(v) if k == 0 && s == 1 => v,
                    _ => &light.v[k],
                }
            }
        };
        let pt = vert(t - 1);
        // Densities recomputed for this connection: from the light side at z_{t−1} and
        // z_{t−2}, from the camera side at y_{s−1} and y_{s−2}; and the light vertex's two
        // densities (drawn by a light subpath, or by next-event estimation).
        let (mut pt_rev, mut ptm_rev, mut qs_rev, mut qsm_rev) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
        let (emit, nee);
        // The density of a vertex `v` (of subpath `sub`, index `i`) sampling `next` after
        // arriving from direction `from` (world, towards where it came from).
        let scatter = |sub: &Subpath, i: usize, from: Vec3, next: &Vertex| -> f32 {
            let v = &sub.v[i];
            let Some((d, _)) = v.towards(next) else {
                return 0.0;
            };
            let Some(bsdf) = sub.bsdf(scene, i) else {
                return 0.0;
            };
            let f = &v.si.frame;
            convert(v.p(), bsdf.pdf(f.to_local(from), f.to_local(d)), next)
        };
        if s == 0 {
            let ptm = vert(t - 2);
            emit = pdf_emit(scene, pt);
            nee = pdf_nee(scene, pt, emit, ptm.p());
            ptm_rev = pdf_light_direction(scene, pt, ptm);
        } else {
            let qs = vert(t);
            qs_rev = if t == 1 {
                match pt.towards(qs) {
                    Some((d, _)) => convert(pt.p(), scene.camera.pdf_direction(d, margin), qs),
                    None => 0.0,
                }
            } else {
                scatter(cam, t - 1, pt.wi, qs)
            };
            if s >= 2 {
                if let Some((d, _)) = qs.towards(pt) {
                    qsm_rev = scatter(light, s - 1, d, vert(t + 1));
                }
            }
            if t >= 2 {
                pt_rev = if s == 1 {
                    pdf_light_direction(scene, qs, pt)
                } else {
                    scatter(light, s - 1, qs.wi, pt)
                };
            }
            if t >= 3 {
                if let Some((d, _)) = pt.towards(qs) {
                    ptm_rev = scatter(cam, t - 1, d, vert(t - 2));
                }
            }
            let y0 = vert(n - 1);
            emit = y0.pdf_emit;
            nee = pdf_nee(scene, y0, emit, vert(n - 2).p());
        }
        let camera_delta = !scene.camera.connects();
        // Whether vertex j scatters through a Dirac delta (the connection's vertices and the
        // light's own do not: they were joined by a connection).
        let delta = |j: usize| -> bool {
            if j == 0 {
                camera_delta
            } else if j == t - 1 || j == t || j == n - 1 {
                false
            } else {
                vert(j).delta
            }
        };
        // Vertex j's density from the camera side and from the light side (j < n − 1); a
        // density that a delta vertex before it made counts as 1.
        let pc = |j: usize| -> f64 {
            if delta(j - 1) {
                return 1.0;
            }
            (if j < t {
                vert(j).pdf_fwd
            } else if j == t {
                qs_rev
            } else if j == t + 1 {
                qsm_rev
            } else {
                vert(j).pdf_rev
            }) as f64
        };
        let pl = |j: usize| -> f64 {
            if delta(j + 1) {
                return 1.0;
            }
            (if j >= t {
                vert(j).pdf_fwd
            } else if j == t - 1 {
                pt_rev
            } else if j == t - 2 {
                ptm_rev
            } else {
                vert(j).pdf_rev
            }) as f64
        };
        // The light vertex's density in strategy s'.
        let end = |sp: usize| -> f64 {
            if sp == 1 {
                nee as f64
            } else {
                emit as f64
            }
        };
        // This strategy's density of the light vertex.
        let end_now = if s == 0 { pc(n - 1) } else { end(s) };
        // (A density this strategy sampled with cannot be 0, but for rounding.)
        let sampled_positive = end_now > 0.0;
        if !sampled_positive {
            return zero;
        }
        // Sample counts: strategies s' >= 2 are drawn in a share of the samples only.
        let share = self.light_share() as f64;
        let count = |sp: usize| if sp >= 2 { share } else { 1.0 };
        let own = count(s);
        let (mut camera_side, mut light_side) = if s >= 2 { (0.0, 1.0) } else { (1.0, 0.0) };
        let mut side = |sp: usize, r: f64| {
            if sp >= 2 {
                light_side += r * r;
            } else {
                camera_side += r * r;
            }
        };
        let mut sum = 0.0f64;
        // Strategies with more light vertices: z_{t−1}, z_{t−2}, ... move to the light side.
        let mut chain = 1.0f64;
        for tp in (1..t).rev() {
            let sp = n - tp;
            if tp != n - 1 {
                let den = pc(tp);
                let positive = den > 0.0;
                if !positive {
                    return zero;
                }
                chain *= pl(tp) / den;
            }
            let r = chain * end(sp) / end_now;
            if !delta(tp - 1) && !delta(tp) {
                side(sp, r);
                let r = r * count(sp) / own;
                sum += r * r;
            }
        }
        // Strategies with fewer light vertices: y_{s−1}, y_{s−2}, ... move to the camera side.
        chain = 1.0;
        for sp in (0..s).rev() {
            let j = n - 1 - sp;
            if sp == 0 {
                let r = chain * pc(n - 1) / end_now;
                if hittable(scene, vert(n - 1)) {
                    side(sp, r);
                    let r = r / own;
                    sum += r * r;
                }
            } else {
                let den = pl(j);
                let positive = den > 0.0;
                if !positive {
                    return zero;
                }
                chain *= pc(j) / den;
                let r = chain * end(sp) / end_now;
                if !delta(j) && !delta(j + 1) {
                    side(sp, r);
                    let r = r * count(sp) / own;
                    sum += r * r;
                }
            }
        }
        if sum.is_finite() && camera_side.is_finite() && light_side.is_finite() {
            Mis {
                weight: (1.0 / (1.0 + sum)) as f32,
                camera_side,
                light_side,
            }
        } else {
            zero
        }
    }
}

/// Whether the camera point `lens` is visible from the surface point `si` when camera rays
/// pass through area emitters (`hide_emitters`): the shadow ray goes on through them.
fn sees_camera_past_emitters(
    scene: &Scene,
    si: &SurfaceInteraction,
    lens: Vec3,
    stats: &mut PathStats,
) -> bool {
    let mut ray = ray_to_camera(si.p, si.p_error, si.ng, lens);
    for _ in 0..=MAX_SKIPPED_EMITTERS {
        let Some(hit) = scene.intersect(&ray) else {
            return true;
        };
        if scene.shapes[hit.shape as usize].emitter.is_none() {
            return false;
        }
        stats.rays += 1;
        ray = ray_to_camera(hit.p, hit.p_error, hit.ng, lens);
    }
    false
}

#[cfg(test)]
// Path vertices are indexed from the camera (j = 0) to the light, as in the text.
#[allow(clippy::needless_range_loop)]
mod tests {
    //! The MIS weights against their definition: paths recorded while rendering small scenes
    //! are split at every vertex, the subpaths each split would have traced are rebuilt
    //! from the path's points (their densities recomputed from the positions, not taken
    //! from the random walks), and the weights of all the strategies that can make the
    //! path must sum to 1; the weight used for the recorded strategy must equal p_s² /
    //! Σ p_{s'}² with each p_{s'} the product of the path's vertex densities.

    use super::*;
    use crate::render::Job;

    /// The path's vertices: camera (0) to light (n − 1), with each surface vertex's BSDF
    /// and whether it scatters through a Dirac delta in this path.
    struct PathPoints {
        v: Vec<Vertex>,
        bsdf: Vec<Option<ShadingBsdf>>,
        delta: Vec<bool>,
        /// The strategy that made it.
        s: usize,
        weight: f32,
    }

    fn path_of(scene: &Scene, c: &Connection) -> PathPoints {
        let (s, t) = (c.s, c.t);
        let n = s + t;
        let mut v = Vec::with_capacity(n);
        let mut bsdf = Vec::with_capacity(n);
        for j in 0..t {
            if j == 0 && t == 1 {
                v.push(c.sampled.expect("lens point"));
                bsdf.push(None);
            } else {
                v.push(c.cam.v[j]);
                bsdf.push(c.cam.bsdf(scene, j).cloned());
            }
        }
        for k in (0..s).rev() {
            if k == 0 && s == 1 {
                v.push(c.sampled.expect("light point"));
                bsdf.push(None);
            } else {
                v.push(c.light.v[k]);
                bsdf.push(c.light.bsdf(scene, k).cloned());
            }
        }
        let delta = (0..n)
            .map(|j| {
                if j == 0 {
                    !scene.camera.connects()
                } else if j == t - 1 || j == t || j == n - 1 {
                    false
                } else {
                    v[j].delta
                }
            })
            .collect();
        PathPoints {
            v,
            bsdf,
            delta,
            s,
            weight: c.weight,
        }
    }

    /// The density with which vertex `at` (a surface, arriving from `from`) scatters towards
    /// `to`, as an area density at `to`.
    fn scatter(p: &PathPoints, at: usize, from: usize, to: usize) -> f32 {
        let (a, f, t) = (&p.v[at], &p.v[from], &p.v[to]);
        let bsdf = p.bsdf[at].as_ref().expect("a surface scatters");
        let (wi, _) = a.towards(f).expect("distinct points");
        let (wo, _) = a.towards(t).expect("distinct points");
        let fr = &a.si.frame;
        convert(a.p(), bsdf.pdf(fr.to_local(wi), fr.to_local(wo)), t)
    }

    /// Every vertex's density from the camera side (pc[j], j ≥ 1) and from the light side
    /// (pl[j], j ≤ n − 2), and the light vertex's two densities (drawn by a light subpath;
    /// by next-event estimation).
    fn densities(scene: &Scene, p: &PathPoints, margin: DVec2) -> (Vec<f32>, Vec<f32>, f32, f32) {
        let n = p.v.len();
        let mut pc = vec![f32::NAN; n];
        let mut pl = vec![f32::NAN; n];
        for j in 1..n {
            pc[j] = if p.delta[j - 1] {
                0.0
            } else if j == 1 {
                let (d, _) = p.v[0].towards(&p.v[1]).expect("distinct");
                convert(p.v[0].p(), scene.camera.pdf_direction(d, margin), &p.v[1])
            } else {
                scatter(p, j - 1, j - 2, j)
            };
        }
        for j in 0..n - 1 {
            pl[j] = if p.delta[j + 1] {
                0.0
            } else if j == n - 2 {
                pdf_light_direction(scene, &p.v[n - 1], &p.v[j])
            } else {
                scatter(p, j + 1, j + 2, j)
            };
        }
        let end = &p.v[n - 1];
        let emit = pdf_emit(scene, end);
        let nee = pdf_nee(scene, end, emit, p.v[n - 2].p());
        (pc, pl, emit, nee)
    }

    /// Whether strategy s' can make the path.
    fn valid(scene: &Scene, p: &PathPoints, sp: usize) -> bool {
        let n = p.v.len();
        if sp == 0 {
            return hittable(scene, &p.v[n - 1]);
        }
        sp < n && !p.delta[n - 1 - sp] && !p.delta[n - sp]
    }

    /// The subpaths strategy s' traces for this path, with the densities the walks would
    /// have stored (NaN where the walks store none: the weight must recompute those), and
    /// the vertex the connection draws.
    fn split(
        p: &PathPoints,
        sp: usize,
        pc: &[f32],
        pl: &[f32],
        emit: f32,
    ) -> (Subpath, Subpath, Option<Vertex>) {
        let n = p.v.len();
        let tp = n - sp;
        let mut cam = Subpath::default();
        let mut light = Subpath::default();
        let own = |sub: &mut Subpath, j: usize, mut v: Vertex| {
            if let Some(b) = &p.bsdf[j] {
                let i = sub.v.len();
                while sub.bsdfs.len() <= i {
                    sub.bsdfs.push(ShadingBsdf::new());
                }
                sub.bsdfs[i] = b.clone();
                v.bsdf = BsdfRef::Own(i as u32);
            } else {
                v.bsdf = BsdfRef::None;
            }
            sub.v.push(v);
        };
        for j in 0..tp {
            let mut v = p.v[j];
            v.delta = p.delta[j];
            if j > 0 {
                if v.kind != Kind::InfiniteLight {
                    v.wi = v.towards(&p.v[j - 1]).expect("distinct").0;
                }
                v.pdf_fwd = pc[j];
                v.pdf_rev = if j + 2 < tp { pl[j] } else { f32::NAN };
            }
            own(&mut cam, j, v);
        }
        for k in 0..sp {
            let j = n - 1 - k;
            let mut v = p.v[j];
            v.delta = p.delta[j];
            if k == 0 {
                v.pdf_emit = emit;
                v.pdf_fwd = emit;
            } else {
                v.wi = v.towards(&p.v[j + 1]).expect("distinct").0;
                v.pdf_fwd = pl[j];
            }
            v.pdf_rev = if k + 2 < sp { pc[j] } else { f32::NAN };
            own(&mut light, j, v);
        }
        let sampled = if tp == 1 {
            Some(cam.v[0])
        } else if sp == 1 {
            Some(light.v[0])
        } else {
            None
        };
        (cam, light, sampled)
    }

    /// Checks every recorded connection of `samples` pixel samples of `xml`; returns how
    /// many paths were checked and how many strategies their sums covered.
    fn check_scene(xml: &str, samples: u64) -> (usize, usize) {
        let job = Job::from_xml_str(xml, std::path::Path::new("inline.xml"), &[]).expect("scene");
        let scene = &job.scene;
        let crate::integrator::Integrator::Bdpt(bdpt) = &job.integrator else {
            panic!("not bdpt");
        };
        let margin = film_margin(scene);
        let mut scratch = Scratch::default();
        let mut stats = PathStats::default();
        let mut splats = Vec::new();
        let mut paths = Vec::new();
        for i in 0..samples {
            let mut stream = SampleStream::new(7, i, 0);
            let pos = stream.next_2d();
            let ray = if scene.camera.needs_aperture_sample() {
                let u = stream.next_2d();
                scene.camera.generate_ray_lens(pos, u)
            } else {
                scene.camera.generate_ray(pos)
            };
            bdpt.sample_recorded(
                scene,
                ray,
                crate::spectrum::NO_WAVELENGTHS,
                &mut stream,
                &mut scratch,
                &mut stats,
                &mut splats,
                &mut |c| {
                    if c.s + c.t > 2 {
                        paths.push(path_of(scene, c))
                    }
                },
            );
            splats.clear();
        }
        let mut strategies = 0;
        for p in &paths {
            let n = p.v.len();
            let (pc, pl, emit, nee) = densities(scene, p, margin);
            // The definition: p_{s'} as the product of the vertex densities (delta-made
            // ones count 1).
            let density = |sp: usize| -> f64 {
                let tp = n - sp;
                let mut prod = 1.0f64;
                for j in 1..tp {
                    prod *= if p.delta[j - 1] { 1.0 } else { pc[j] as f64 };
                }
                for j in tp..n - 1 {
                    prod *= if p.delta[j + 1] { 1.0 } else { pl[j] as f64 };
                }
                if sp >= 1 {
                    prod *= if sp == 1 { nee } else { emit } as f64;
                }
                prod
            };
            let strategies_of: Vec<usize> = (0..n).filter(|&sp| valid(scene, p, sp)).collect();
            assert!(
                strategies_of.contains(&p.s),
                "the recorded strategy is not valid"
            );
            // With sample counts: strategies s' >= 2 are drawn in a share of the samples.
            let share = bdpt.light_share() as f64;
            let counted = |sp: usize| density(sp) * if sp >= 2 { share } else { 1.0 };
            let total: f64 = strategies_of.iter().map(|&sp| counted(sp).powi(2)).sum();
            let want = counted(p.s).powi(2) / total;
            // The walks' densities come from the directions of rays leaving offset origins
            // (f32), the definition's from the points' differences: on the glossiest lobe
            // here (α = 0.05) they differ by up to ~3e-3 relatively (measured); a wrong
            // weight is off by far more.
            assert!(
                (p.weight as f64 - want).abs() <= 1e-2 * want.max(1e-3),
                "n {n}, s {}: weight {} against (c_s p_s)²/Σ(c p)² = {want}",
                p.s,
                p.weight
            );
            let mut sum = 0.0f64;
            for &sp in &strategies_of {
                let (cam, light, sampled) = split(p, sp, &pc, &pl, emit);
                let w = bdpt
                    .mis(scene, &cam, &light, sampled.as_ref(), sp, n - sp, margin)
                    .weight;
                assert!(w.is_finite(), "n {n}, s' {sp}: weight {w}");
                sum += w as f64;
            }
            strategies += strategies_of.len();
            assert!(
                (sum - 1.0).abs() < 1e-4,
                "n {n}, recorded s {}: weights sum to {sum}",
                p.s
            );
        }
        (paths.len(), strategies)
    }

    fn scene(integrator: &str, sensor: &str, content: &str) -> String {
        format!(
            r#"<scene version="3.0.0">
                <integrator type="bdpt">{integrator}</integrator>
                {sensor}
                {content}
            </scene>"#
        )
    }

    const PINHOLE: &str = r#"<sensor type="perspective"><float name="fov" value="60"/>
        <transform name="to_world"><lookat origin="0, 0.2, 1.9" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film></sensor>"#;

    /// A box of diffuse, glossy and specular surfaces (a smooth plastic and a glass sphere,
    /// a mirror), lit by a rectangle, a sphere light (cone-sampled from outside), a point
    /// light and a spot light.
    fn room(lights: &str) -> String {
        format!(
            r#"<shape type="cube"><boolean name="flip_normals" value="true"/>
                <transform name="to_world"><scale value="2"/></transform>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf></shape>
            <shape type="sphere"><point name="center" x="-0.8" y="-1.2" z="0"/><float name="radius" value="0.6"/>
                <bsdf type="roughplastic"><float name="alpha" value="0.2"/></bsdf></shape>
            <shape type="sphere"><point name="center" x="0.8" y="-1.3" z="0.4"/><float name="radius" value="0.5"/>
                <bsdf type="dielectric"/></shape>
            <shape type="rectangle">
                <transform name="to_world"><scale value="0.5"/><rotate y="1" angle="90"/><translate x="-1.95" y="0.5"/></transform>
                <bsdf type="roughconductor"><float name="alpha" value="0.05"/></bsdf></shape>
            <shape type="disk">
                <transform name="to_world"><scale value="0.4"/><rotate x="1" angle="-90"/><translate z="-1.9" y="0.3"/></transform>
                <bsdf type="plastic"/></shape>
            {lights}"#
        )
    }

    const LIGHTS: &str = r#"<shape type="rectangle">
            <transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate y="1.99"/></transform>
            <emitter type="area"><rgb name="radiance" value="10"/></emitter></shape>
        <shape type="sphere"><point name="center" x="1.2" y="1.2" z="-1"/><float name="radius" value="0.2"/>
            <emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>
        <emitter type="point"><point name="position" x="-1" y="1.5" z="1"/><rgb name="intensity" value="2"/></emitter>
        <emitter type="spot"><transform name="to_world"><lookat origin="1, 1.8, 1.5" target="0, -2, 0" up="0, 1, 0"/></transform>
            <rgb name="intensity" value="4"/></emitter>"#;

    fn texture(name: &str) -> String {
        format!(
            "{}/validation/mitsuba-suite/common/textures/{name}",
            env!("CARGO_MANIFEST_DIR")
        )
    }

    /// Diffuse, glossy and specular surfaces lit by a rectangle, a sphere light (sampled by
    /// its cone from outside), a point light and a spot light, seen by a pinhole.
    #[test]
    fn mis_weights_sum_to_one_in_a_room() {
        let (paths, strategies) = check_scene(
            &scene(
                r#"<integer name="max_depth" value="6"/>"#,
                PINHOLE,
                &room(LIGHTS),
            ),
            3000,
        );
        assert!(
            paths > 5000 && strategies > 3 * paths,
            "{paths} paths, {strategies} strategies"
        );
    }

    /// The same room with light subpaths traced in 30% of the samples: the weights count
    /// the strategies s ≥ 2 with that share (Veach's MIS with sample counts) and still sum
    /// to one.
    #[test]
    fn mis_weights_sum_to_one_with_a_share_of_light_subpaths() {
        let (paths, strategies) = check_scene(
            &scene(
                r#"<integer name="max_depth" value="6"/><float name="light_paths" value="0.3"/>"#,
                PINHOLE,
                &room(LIGHTS),
            ),
            3000,
        );
        assert!(
            paths > 2000 && strategies > 3 * paths,
            "{paths} paths, {strategies} strategies"
        );
    }

    /// Emitters at infinity (an environment map and a directional light) over an open
    /// floor with a glass sphere and a rough dielectric, through a thin lens.
    #[test]
    fn mis_weights_sum_to_one_under_the_sky() {
        let sensor = r#"<sensor type="thinlens"><float name="fov" value="50"/>
            <float name="aperture_radius" value="0.1"/><float name="focus_distance" value="4"/>
            <transform name="to_world"><lookat origin="0, 1.5, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film></sensor>"#;
        let content = format!(
            r#"<shape type="rectangle"><transform name="to_world"><scale value="5"/><rotate x="1" angle="-90"/></transform>
                <bsdf type="diffuse"/></shape>
            <shape type="sphere"><point name="center" x="-0.6" y="0.5" z="0"/><float name="radius" value="0.5"/>
                <bsdf type="dielectric"/></shape>
            <shape type="sphere"><point name="center" x="0.7" y="0.4" z="0.3"/><float name="radius" value="0.4"/>
                <bsdf type="roughdielectric"><float name="alpha" value="0.3"/></bsdf></shape>
            <shape type="sphere"><point name="center" x="0" y="0.3" z="1"/><float name="radius" value="0.3"/>
                <bsdf type="principled"><float name="roughness" value="0.4"/><float name="metallic" value="0.3"/></bsdf></shape>
            <emitter type="envmap"><string name="filename" value="{}"/></emitter>
            <emitter type="directional"><vector name="direction" x="1" y="-2" z="-0.5"/>
                <rgb name="irradiance" value="3"/></emitter>"#,
            texture("museum.exr")
        );
        let (paths, strategies) = check_scene(
            &scene(r#"<integer name="max_depth" value="5"/>"#, sensor, &content),
            3000,
        );
        assert!(
            paths > 3000 && strategies > 2 * paths,
            "{paths} paths, {strategies} strategies"
        );
    }

    /// An orthographic camera (no connection to it), camera rays passing through emitters
    /// (`hide_emitters`), a textured area light, a mask, a thin dielectric and a two-sided
    /// BSDF, a constant environment.
    #[test]
    fn mis_weights_sum_to_one_with_an_orthographic_camera_and_hidden_emitters() {
        let sensor = r#"<sensor type="orthographic">
            <transform name="to_world"><scale x="2" y="2"/><lookat origin="0.3, 1.5, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film></sensor>"#;
        let content = format!(
            r#"<shape type="rectangle"><transform name="to_world"><scale value="5"/><rotate x="1" angle="-90"/></transform>
                <bsdf type="twosided"><bsdf type="roughconductor"><float name="alpha" value="0.3"/></bsdf></bsdf></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="0.8"/><translate y="0.8" z="-0.5"/></transform>
                <bsdf type="mask"><texture type="bitmap" name="opacity"><string name="filename" value="{}"/></texture>
                    <bsdf type="diffuse"/></bsdf></shape>
            <shape type="sphere"><point name="center" x="0.8" y="0.4" z="0.5"/><float name="radius" value="0.4"/>
                <bsdf type="thindielectric"/></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="0.5"/><rotate x="1" angle="30"/><translate x="-0.5" y="1.2" z="1"/></transform>
                <emitter type="area"><texture type="bitmap" name="radiance"><string name="filename" value="{}"/></texture></emitter></shape>
            <emitter type="constant"><rgb name="radiance" value="0.3"/></emitter>"#,
            texture("leaf_mask.png"),
            texture("flower.bmp")
        );
        let (paths, strategies) = check_scene(
            &scene(
                r#"<integer name="max_depth" value="5"/><boolean name="hide_emitters" value="true"/>"#,
                sensor,
                &content,
            ),
            3000,
        );
        assert!(
            paths > 2000 && strategies > 2 * paths,
            "{paths} paths, {strategies} strategies"
        );
    }
}
