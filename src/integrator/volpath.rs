//! Mitsuba's `volpath`: volumetric path tracing (Mitsuba 3's `VolumetricPathIntegrator`).
//! Paths scatter on surfaces and inside participating media ([`crate::medium`]): distances
//! are sampled by delta tracking against the medium's majorant (Woodcock et al. 1965; Novák
//! et al. 2018, "Monte Carlo methods for volumetric light transport simulation", §5), shadow
//! rays carry ratio-tracked transmittance and cross index-matched (`null`) and thin-dielectric
//! surfaces with their null transmission, and next-event estimation at surfaces and medium
//! events is combined with BSDF / phase-function sampling by the power heuristic.
//!
//! Mitsuba's semantics, followed exactly:
//! - RGB media are tracked in one channel per path, chosen uniformly at the start; the other
//!   channels are weighed by their transmittance over that channel's free-flight density. In
//!   spectral mode the path's first wavelength drives the tracking (Mitsuba's `channel` 0;
//!   the four wavelengths are sampled with random offsets, so it is a random one) and means
//!   over channels run over the four wavelengths.
//! - Depth counts scattering events: surface bounces that are not `null` events, and real
//!   medium collisions; null surfaces (`null`, a mask's holes, a thin dielectric's straight
//!   transmission) and null collisions do not count. `max_depth` −1 is unbounded.
//! - Russian roulette from depth > `rr_depth` on, q = min(max(throughput) · η², 0.95), tested
//!   at every loop iteration.
//! - An emitter hit is MIS-weighted against next-event estimation from the last scattering
//!   event unless the path since then was a chain of delta bounces (or started at the camera).
//! - A shape with media changes the current medium when a ray leaves it (see
//!   [`Scene::target_medium`]); camera rays start in the sensor's medium.
//!
//! | parameter | default |
//! |---|---|
//! | `max_depth` | −1 (unbounded) |
//! | `rr_depth` | 5 |
//! | `hide_emitters` | false |

use crate::emitter::DirectionSample;
use crate::geometry::Ray;
use crate::integrator::{emission_at, emitter_pdf_at, PathStats};
use crate::material::ShadingBsdf;
use crate::medium::{mean, safe_div, transmittance, Medium, MediumInteraction};
use crate::sampler::SampleStream;
use crate::sampling::mis_power;
use crate::scene::Scene;
use crate::shape::SurfaceInteraction;
use crate::spectrum::{Mode, Spectrum};
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct VolPathIntegrator {
    /// Longest path, in scattering events; `u32::MAX` for unbounded.
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
}

/// Where a next-event estimation sample starts.
#[derive(Clone, Copy)]
pub(crate) enum Vertex<'a> {
    Surface(&'a SurfaceInteraction),
    Medium(Vec3),
}

/// What a shadow ray accumulates on its way to the emitter: the transmittance estimate (for
/// `volpath`) or the MIS weight matrices (for `volpathmis`).
pub(crate) trait ShadowWeights {
    /// A sampled free-flight segment: majorant transmittance `tr` and its density `pdf`.
    fn segment(&mut self, tr: Spectrum, pdf: Spectrum, channel: usize);
    /// A null collision `mi` passed through (ratio tracking).
    fn collision(&mut self, mi: &MediumInteraction, channel: usize);
    /// A surface crossed with null transmission `t`.
    fn surface(&mut self, t: Spectrum, channel: usize);
    /// Nothing more can arrive.
    fn is_zero(&self) -> bool;
}

/// Picks the channel that drives distance sampling for a whole path: one of R, G, B in RGB
/// mode, the first wavelength in spectral mode (Mitsuba's spectral variants).
#[inline]
pub(crate) fn pick_channel(u: f32, mode: Mode) -> usize {
    match mode {
        Mode::Rgb => ((u * 3.0) as usize).min(2),
        Mode::Spectral => 0,
    }
}

/// The value of channel `c`.
#[inline]
pub(crate) fn channel_of(v: Spectrum, c: usize) -> f32 {
    v[c]
}

/// One delta-tracking step along `ray` in `med` (Mitsuba's loop body): a tentative collision
/// drawn with `channel`'s majorant (in a homogeneous medium, whose collisions are all real,
/// the ray is cut there, at most at `limit`), the closest surface along the ray (intersected
/// once and kept in `hit`), and the collision dropped when that surface comes first. Returns
/// the collision and the surface's distance (∞ without one).
#[allow(clippy::too_many_arguments)]
pub(crate) fn track_step(
    scene: &Scene,
    med: &Medium,
    ray: &mut Ray,
    limit: f32,
    hit: &mut Option<Option<SurfaceInteraction>>,
    channel: usize,
    wl: Vec4,
    sampler: &mut SampleStream,
    stats: &mut PathStats,
) -> (MediumInteraction, f32) {
    let mut mi = med.sample_interaction(ray, sampler.next_1d(), channel, wl);
    if med.is_homogeneous() && mi.is_valid() {
        ray.tmax = mi.t.min(limit);
    }
    let si = *hit.get_or_insert_with(|| {
        stats.rays += 1;
        scene.intersect(ray)
    });
    let si_t = si.map_or(f32::INFINITY, |s| s.t);
    if si_t < mi.t {
        mi.t = f32::INFINITY;
    }
    (mi, si_t)
}

/// Moves the ray's origin to the (null) collision `mi`, keeping the surface found ahead.
#[inline]
pub(crate) fn pass_collision(
    ray: &mut Ray,
    hit: &mut Option<Option<SurfaceInteraction>>,
    mi: &MediumInteraction,
) {
    ray.o = mi.p;
    if let Some(Some(s)) = hit.as_mut() {
        s.t -= mi.t;
    }
}

/// Traces the shadow ray of emitter sample `ds` from `from` through media and null surfaces
/// (Mitsuba's `sample_emitter` loop), reporting what it meets to `w`. `medium` is the medium
/// the path is in at `from`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_shadow<W: ShadowWeights>(
    scene: &Scene,
    from: Vertex,
    ds: &DirectionSample,
    mut medium: Option<u32>,
    channel: usize,
    wl: Vec4,
    sampler: &mut SampleStream,
    stats: &mut PathStats,
    w: &mut W,
) {
    let mut ray = match from {
        Vertex::Surface(si) => Scene::shadow_ray(si, ds),
        Vertex::Medium(p) => Scene::shadow_ray_from_point(p, ds),
    };
    if !ray.d.is_finite() {
        return;
    }
    if !scene.shadow_passthrough {
        // No media and nothing to see through: any surface blocks the light.
        stats.rays += 1;
        if scene.occluded(&ray) {
            w.surface(Spectrum::ZERO, channel);
        }
        return;
    }
    let max_dist = ray.tmax;
    if let Vertex::Surface(si) = from {
        if scene.is_medium_transition(si) {
            medium = scene.target_medium(si, ray.d);
        }
    }
    let mut total = 0.0f32;
    // The closest surface along the current ray, once intersected.
    let mut hit: Option<Option<SurfaceInteraction>> = None;
    loop {
        let remaining = max_dist - total;
        if remaining.is_nan() || remaining <= 0.0 {
            return;
        }
        ray.tmax = remaining;
        if let Some(m) = medium {
            let med = &scene.media[m as usize];
            let (mut mi, si_t) = track_step(
                scene, med, &mut ray, remaining, &mut hit, channel, wl, sampler, stats,
            );
            let t = mi.segment(remaining.min(si_t));
            let tr = transmittance(t, mi.combined_extinction);
            let pdf = if si_t < mi.t || mi.t > remaining {
                tr
            } else {
                tr * mi.combined_extinction
            };
            w.segment(tr, pdf, channel);
            if mi.t > remaining {
                mi.t = f32::INFINITY;
            }
            if mi.is_valid() {
                // A collision before the surface: pass it as a null one.
                total += mi.t;
                pass_collision(&mut ray, &mut hit, &mi);
                w.collision(&mi, channel);
                if w.is_zero() {
                    return;
                }
                continue;
            }
        }
        let si = match hit.take() {
            Some(si) => si,
            None => {
                stats.rays += 1;
                scene.intersect(&ray)
            }
        };
        let Some(si) = si else {
            return;
        };
        total += si.t;
        let bsdf = scene.shading_bsdf(&si, wl);
        w.surface(bsdf.null_transmission(si.frame.to_local(-ray.d)), channel);
        if w.is_zero() {
            return;
        }
        ray = Scene::spawn_ray(&si, ray.d);
        if scene.is_medium_transition(&si) {
            medium = scene.target_medium(&si, ray.d);
        }
    }
}

/// `volpath`'s shadow-ray weight: the transmittance estimate.
struct Transmittance(Spectrum);

impl ShadowWeights for Transmittance {
    #[inline]
    fn segment(&mut self, tr: Spectrum, pdf: Spectrum, channel: usize) {
        let p = channel_of(pdf, channel);
        self.0 *= if p > 0.0 { tr / p } else { Spectrum::ZERO };
    }
    #[inline]
    fn collision(&mut self, mi: &MediumInteraction, _channel: usize) {
        self.0 *= mi.sigma_n;
    }
    #[inline]
    fn surface(&mut self, t: Spectrum, _channel: usize) {
        self.0 *= t;
    }
    #[inline]
    fn is_zero(&self) -> bool {
        self.0 == Spectrum::ZERO || !self.0.is_finite()
    }
}

impl VolPathIntegrator {
    /// Next-event estimation from `from`: the emitter's radiance over the sample's density
    /// times the shadow ray's transmittance, and the sample.
    fn sample_emitter(
        scene: &Scene,
        from: Vertex,
        medium: Option<u32>,
        channel: usize,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Option<(Spectrum, DirectionSample)> {
        let p = match from {
            Vertex::Surface(si) => si.p,
            Vertex::Medium(p) => p,
        };
        let ds = scene.sample_emitter_direction_at(p, sampler.next_2d(), wl)?;
        if ds.pdf.is_nan() || ds.pdf <= 0.0 {
            return None;
        }
        let mut tr = Transmittance(Spectrum::ONE);
        trace_shadow(
            scene, from, &ds, medium, channel, wl, sampler, stats, &mut tr,
        );
        if tr.is_zero() {
            return None;
        }
        Some((tr.0 * ds.radiance / ds.pdf, ds))
    }

    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        let mut ray = Ray::new(ray.o, ray.d.normalize(), ray.tmax);
        let mut result = Spectrum::ZERO;
        let mut throughput = Spectrum::ONE;
        let mut eta = 1.0f32;
        let mut depth = 0u32;
        let mut medium = scene.camera_medium;
        let mut specular_chain = !self.hide_emitters;
        let mode = scene.mode;
        let channel = pick_channel(sampler.next_1d(), mode);
        // The closest surface along the current ray, once intersected.
        let mut hit: Option<Option<SurfaceInteraction>> = None;
        let mut last_scatter_p = ray.o;
        let mut last_scatter_pdf = 1.0f32;
        // Filled in place at surface vertices whose material varies (see `Scene::bsdf_at`).
        let mut bsdf_buf = ShadingBsdf::new();
        loop {
            // Russian roulette and the depth limit.
            if throughput == Spectrum::ZERO || !throughput.is_finite() {
                break;
            }
            if depth > self.rr_depth {
                let q = (throughput.max_element() * eta * eta).min(0.95);
                if sampler.next_1d() >= q {
                    stats.rr_terminated += 1;
                    break;
                }
                throughput /= q;
            }
            if depth >= self.max_depth {
                break;
            }

            // Sampling the medium the ray travels in.
            let mut escaped_medium = medium.is_none();
            if let Some(m) = medium {
                let med: &Medium = &scene.media[m as usize];
                let (mi, si_t) = track_step(
                    scene,
                    med,
                    &mut ray,
                    f32::INFINITY,
                    &mut hit,
                    channel,
                    wl,
                    sampler,
                    stats,
                );
                let (tr, pdf) = Medium::transmittance_eval_pdf(&mi, si_t);
                let tr_pdf = channel_of(pdf, channel);
                throughput *= if tr_pdf > 0.0 {
                    tr / tr_pdf
                } else {
                    Spectrum::ZERO
                };
                if mi.is_valid() {
                    let null_prob = mean(safe_div(mi.sigma_n, mi.combined_extinction), mode);
                    if sampler.next_1d() < null_prob {
                        // A null collision: continue along the ray from there.
                        throughput *= mi.sigma_n / null_prob;
                        pass_collision(&mut ray, &mut hit, &mi);
                        continue;
                    }
                    // A real collision: scatter.
                    depth += 1;
                    if depth >= self.max_depth {
                        break;
                    }
                    stats.bounces += 1;
                    throughput *=
                        mi.sigma_s / mean(safe_div(mi.sigma_t, mi.combined_extinction), mode);
                    last_scatter_p = mi.p;
                    specular_chain = !med.sample_emitters;
                    if med.sample_emitters {
                        if let Some((emitted, ds)) = Self::sample_emitter(
                            scene,
                            Vertex::Medium(mi.p),
                            medium,
                            channel,
                            wl,
                            sampler,
                            stats,
                        ) {
                            let phase_val = med.phase.eval(mi.wi, ds.d);
                            let w = if ds.delta {
                                1.0
                            } else {
                                mis_power(ds.pdf, phase_val)
                            };
                            result += throughput * phase_val * emitted * w;
                        }
                    }
                    let Some(ps) = med.phase.sample(mi.wi, sampler.next_2d()) else {
                        break;
                    };
                    throughput *= ps.weight;
                    last_scatter_pdf = ps.pdf;
                    ray = Ray::new(mi.p, ps.wo, f32::INFINITY);
                    hit = None;
                    continue;
                }
                escaped_medium = true;
            }
            debug_assert!(escaped_medium);

            // The surface the ray reaches (or the environment).
            let mut si = match hit.take() {
                Some(si) => si,
                None => {
                    stats.rays += 1;
                    scene.intersect(&ray)
                }
            };
            if self.hide_emitters && depth == 0 {
                si = super::pass_through_emitters(scene, ray.d, si, stats);
            }
            if !(depth == 0 && self.hide_emitters) {
                let le = emission_at(scene, si.as_ref(), ray.d, wl);
                if le != Spectrum::ZERO {
                    let count_direct = depth == 0 || specular_chain;
                    let w = if count_direct {
                        1.0
                    } else {
                        mis_power(
                            last_scatter_pdf,
                            emitter_pdf_at(scene, last_scatter_p, si.as_ref(), ray.d),
                        )
                    };
                    result += throughput * le * w;
                }
            }
            let Some(si) = si else {
                break;
            };
            let bsdf = scene.bsdf_at(&si, wl, &mut bsdf_buf);
            let wi = si.frame.to_local(-ray.d);

            // Next-event estimation.
            if depth.saturating_add(1) < self.max_depth && bsdf.has_smooth_lobe(wi) {
                if let Some((emitted, ds)) = Self::sample_emitter(
                    scene,
                    Vertex::Surface(&si),
                    medium,
                    channel,
                    wl,
                    sampler,
                    stats,
                ) {
                    let wo = si.frame.to_local(ds.d);
                    let f = bsdf.eval(wi, wo);
                    if f != Spectrum::ZERO {
                        let w = if ds.delta {
                            1.0
                        } else {
                            mis_power(ds.pdf, bsdf.pdf(wi, wo))
                        };
                        result += throughput * f * emitted * w;
                    }
                }
            }

            // BSDF sampling.
            let u1 = sampler.next_1d();
            let u2 = sampler.next_2d();
            let Some(bs) = bsdf.sample(wi, u1, u2) else {
                break;
            };
            throughput *= bs.weight;
            eta *= bs.eta;
            let wo_world = si.frame.to_world(bs.wo).normalize();
            ray = Scene::spawn_ray(&si, wo_world);
            hit = None;
            if !bs.null {
                depth += 1;
                stats.bounces += 1;
                last_scatter_p = si.p;
                last_scatter_pdf = bs.pdf;
                if bs.delta {
                    specular_chain = true;
                }
            }
            if !bs.delta {
                specular_chain = false;
            }
            if scene.is_medium_transition(&si) {
                medium = scene.target_medium(&si, ray.d);
            }
        }
        result
    }
}
