//! Integrators: estimators of the radiance arriving along a camera ray, and the steps they
//! share (emission where a ray ends, and one next-event estimation sample).

pub mod aov;
pub mod bdpt;
pub mod build;
pub mod direct;
pub mod lanes;
pub mod path;
pub mod ptracer;
pub mod radiosity;
pub mod sppm;
pub mod volpath;
pub mod volpathmis;
pub mod whitted;

pub use bdpt::Bdpt;
pub use direct::DirectIntegrator;
pub use path::PathIntegrator;
pub use ptracer::ParticleTracer;
pub use sppm::Sppm;
pub use volpath::VolPathIntegrator;
pub use volpathmis::VolPathMisIntegrator;
pub use whitted::WhittedIntegrator;

use crate::emitter::Emitter;
use crate::geometry::Ray;
use crate::material::ShadingBsdf;
use crate::sampler::SampleStream;
use crate::scene::Scene;
use crate::shape::SurfaceInteraction;
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3, Vec4};

/// Counters gathered while tracing, summed over a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PathStats {
    /// Rays traced: closest-hit plus shadow rays.
    pub rays: u64,
    /// Path vertices on surfaces.
    pub bounces: u64,
    /// Paths ended by Russian roulette.
    pub rr_terminated: u64,
}

impl std::ops::AddAssign for PathStats {
    fn add_assign(&mut self, o: Self) {
        self.rays += o.rays;
        self.bounces += o.bounces;
        self.rr_terminated += o.rr_terminated;
    }
}

#[derive(Clone, Debug)]
pub enum Integrator {
    Path(PathIntegrator),
    Direct(DirectIntegrator),
    /// Mitsuba's arbitrary output variables (depth, normals, ...; rendered group by group).
    Aov(aov::AovIntegrator),
    /// Classic recursive ray tracing (penumbra's own).
    Whitted(WhittedIntegrator),
    /// Radiosity (penumbra's own): the render driver solves it before the first pass
    /// ([`radiosity::RadiosityIntegrator::prepare`]).
    Radiosity(radiosity::RadiosityIntegrator),
    VolPath(VolPathIntegrator),
    VolPathMis(VolPathMisIntegrator),
    /// Light tracing: not an estimator of camera-ray radiance, so [`Integrator::li`] does
    /// not apply; the render driver traces particles instead (`render::render`).
    ParticleTracer(ParticleTracer),
    /// Stochastic progressive photon mapping: like the particle tracer, rendered by the
    /// driver as a whole ([`Sppm::render`]).
    Sppm(Sppm),
    /// Bidirectional path tracing: its light-tracing strategy splats anywhere on the film,
    /// so the driver renders it pass by pass (`render::render`).
    Bdpt(Bdpt),
}

impl Integrator {
    /// This integrator with what a render settles before its first sample settled:
    /// `bdpt`'s share of light subpaths, where the scene leaves it open (a pilot render,
    /// [`Bdpt::resolved`]), for a render of `spp` samples per pixel in all. A progressive
    /// render settles it once, before its first pass.
    pub fn resolved(
        &self,
        scene: &Scene,
        seed: u64,
        spp: u64,
        pool: &rayon::ThreadPool,
    ) -> Integrator {
        match self {
            Integrator::Bdpt(b) => Integrator::Bdpt(b.resolved(scene, seed, spp, pool)),
            other => other.clone(),
        }
    }

    /// Whether the integrator renders in spectral mode (`--mode spectral`) yet.
    pub fn supports_spectral(&self) -> bool {
        matches!(
            self,
            Integrator::Path(_)
                | Integrator::Direct(_)
                | Integrator::VolPath(_)
                | Integrator::VolPathMis(_)
                | Integrator::ParticleTracer(_)
                | Integrator::Bdpt(_)
        ) || matches!(self, Integrator::Aov(a) if a.nested.iter().all(|(_, i)| i.supports_spectral()))
    }

    /// Whether [`Integrator::li`] returns a spectrum, which spectral mode converts to RGB:
    /// all but the geometric channels of `aov` (depth, normals, ...), which are numbers.
    pub fn outputs_spectrum(&self) -> bool {
        match self {
            Integrator::Aov(a) => a.outputs_spectrum(),
            _ => true,
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Integrator::Path(_) => "path",
            Integrator::Direct(_) => "direct",
            Integrator::Aov(_) => "aov",
            Integrator::Whitted(_) => "whitted",
            Integrator::Radiosity(_) => "radiosity",
            Integrator::VolPath(_) => "volpath",
            Integrator::VolPathMis(_) => "volpathmis",
            Integrator::ParticleTracer(_) => "ptracer",
            Integrator::Sppm(_) => "sppm",
            Integrator::Bdpt(_) => "bdpt",
        }
    }

    #[inline]
    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        match self {
            Integrator::Path(p) => p.li(scene, ray, wl, sampler, stats),
            Integrator::Direct(d) => d.li(scene, ray, wl, sampler, stats),
            Integrator::Aov(a) => a.li(scene, ray, wl, sampler, stats),
            // RGB only (`Integrator::supports_spectral`):
            Integrator::Whitted(w) => w.li(scene, ray, sampler, stats),
            Integrator::Radiosity(r) => r.li_with_solution(scene, ray, sampler, stats),
            Integrator::VolPath(v) => v.li(scene, ray, wl, sampler, stats),
            Integrator::VolPathMis(v) => v.li(scene, ray, wl, sampler, stats),
            // The render driver never asks a light tracer for camera-ray radiance.
            Integrator::ParticleTracer(_) | Integrator::Sppm(_) | Integrator::Bdpt(_) => {
                Spectrum::ZERO
            }
        }
    }
}

/// The radiance arriving along a ray of direction `d` from where it ended: the area emitter
/// of the surface it hit (one-sided), or the environment when it escaped (`hit` is `None`).
#[inline]
pub(crate) fn emission_at(
    scene: &Scene,
    hit: Option<&SurfaceInteraction>,
    d: Vec3,
    wl: Vec4,
) -> Spectrum {
    match hit {
        None => scene.eval_environment(d, wl),
        Some(si) => match scene.shapes[si.shape as usize].emitter {
            Some(e) => match &scene.emitters[e as usize] {
                Emitter::Area(area) => area.eval(si, -d.normalize(), &scene.shapes, wl),
                _ => Spectrum::ZERO,
            },
            None => Spectrum::ZERO,
        },
    }
}

/// The solid-angle density with which emitter sampling from `p_ref` produces where a ray of
/// direction `d` ended (as [`emission_at`]); 0 where nothing emits.
#[inline]
pub(crate) fn emitter_pdf_at(
    scene: &Scene,
    p_ref: Vec3,
    hit: Option<&SurfaceInteraction>,
    d: Vec3,
) -> f32 {
    match hit {
        None => scene.pdf_environment(d),
        Some(si) => scene.pdf_emitter_direction(p_ref, si),
    }
}

/// Area emitters a hidden camera ray passes through before giving up (a ray crossing more
/// stacked lights renders black). One rule for every integrator with `hide_emitters` that
/// passes through emitters in a separate step (direct, whitted, volpath, volpathmis).
pub(crate) const MAX_SKIPPED_EMITTERS: u32 = 256;

/// Where a camera ray of direction `d` ends when it passes through area emitters
/// (`hide_emitters`, Mitsuba's `skip_area_emitters`): `hit`
/// (the ray's first hit) if it does not emit, else the first surface after the emitters
/// that does not; `None` when the ray leaves the scene or crosses more than
/// [`MAX_SKIPPED_EMITTERS`] of them.
pub(crate) fn pass_through_emitters(
    scene: &Scene,
    d: Vec3,
    mut hit: Option<SurfaceInteraction>,
    stats: &mut PathStats,
) -> Option<SurfaceInteraction> {
    let mut skipped = 0;
    while let Some(si) = &hit {
        if scene.shapes[si.shape as usize].emitter.is_none() {
            break;
        }
        skipped += 1;
        if skipped > MAX_SKIPPED_EMITTERS {
            return None;
        }
        let next = Scene::spawn_ray(si, d);
        stats.rays += 1;
        hit = scene.intersect(&next);
    }
    hit
}

/// One sample of next-event estimation at `si`, visibility tested: f · L / pdf, and the two
/// densities its caller's MIS weight needs (the BSDF's only for non-delta emitters).
pub(crate) struct EmitterSample {
    pub value: Spectrum,
    pub emitter_pdf: f32,
    pub bsdf_pdf: f32,
    /// A delta emitter: BSDF sampling cannot find it, so no MIS.
    pub delta: bool,
}

/// Picks an emitter and a point on it (`u`), evaluates the BSDF towards it and traces the
/// shadow ray; `None` when the sample contributes nothing.
#[inline]
pub(crate) fn sample_emitter(
    scene: &Scene,
    si: &SurfaceInteraction,
    bsdf: &ShadingBsdf,
    wi: Vec3,
    u: Vec2,
    wl: Vec4,
    stats: &mut PathStats,
) -> Option<EmitterSample> {
    let ds = scene.sample_emitter_direction(si, u, wl)?;
    connect_emitter(scene, si, bsdf, wi, &ds, stats)
}

/// Next-event estimation towards the emitter point `ds` (sampled by the caller): the BSDF
/// towards it and the shadow ray; `None` when it contributes nothing.
#[inline]
pub(crate) fn connect_emitter(
    scene: &Scene,
    si: &SurfaceInteraction,
    bsdf: &ShadingBsdf,
    wi: Vec3,
    ds: &crate::emitter::DirectionSample,
    stats: &mut PathStats,
) -> Option<EmitterSample> {
    let wo = si.frame.to_local(ds.d);
    let f = bsdf.eval(wi, wo);
    if f == Spectrum::ZERO {
        return None;
    }
    stats.rays += 1;
    if scene.occluded(&Scene::shadow_ray(si, ds)) {
        return None;
    }
    Some(EmitterSample {
        value: f * ds.radiance / ds.pdf,
        emitter_pdf: ds.pdf,
        bsdf_pdf: if ds.delta { 0.0 } else { bsdf.pdf(wi, wo) },
        delta: ds.delta,
    })
}
