//! Mitsuba's `volpathmis`: volumetric path tracing with spectral and emitter MIS (Miller,
//! Georgiev and Jarosz 2019, "A null-scattering path integral formulation of light
//! transport"), Mitsuba 3's `VolpathMisIntegratorImpl`.
//!
//! The same paths as [`super::volpath`] (one RGB channel drives distance sampling, chosen per
//! path; in spectral mode the first of the path's four wavelengths), but every estimate is
//! weighted by the balance heuristic over all the ways the path could have been made: the
//! channels' tracking densities (three in RGB mode, four wavelengths in spectral mode, as
//! Mitsuba's `dr::size_v<Spectrum>`; spectral MIS: the estimate
//! of channel i is f_i / mean_j p_j, the one-sample MIS of Veach 1997 §9.2.4, which removes
//! the fireflies of a channel with a much lower extinction) and, for emitter hits, unidirectional
//! sampling against next-event estimation, whose density includes the ratio-tracked shadow
//! ray's. The path keeps, instead of a throughput, the ratios p / f of every event's density
//! to its contribution: an n × n matrix (p_j / f_i) with spectral MIS, a vector
//! (p_channel / f_i) without (`use_spectral_mis` false).
//!
//! Depth, Russian roulette (not after null collisions), media transitions and
//! `hide_emitters` follow [`super::volpath`]. As in Mitsuba 3.9.1, surfaces crossed by null
//! events weigh the unidirectional and NEE densities as if the null lobe were taken with
//! probability 1; for `null` BSDFs that is exact.
//!
//! | parameter | default |
//! |---|---|
//! | `max_depth` | −1 (unbounded) |
//! | `rr_depth` | 5 |
//! | `hide_emitters` | false |
//! | `use_spectral_mis` | true |

use super::volpath::{
    pass_collision, pick_channel, trace_shadow, track_step, ShadowWeights, Vertex,
};
use crate::emitter::DirectionSample;
use crate::geometry::Ray;
use crate::integrator::{emission_at, emitter_pdf_at, PathStats};
use crate::material::ShadingBsdf;
use crate::medium::{mean, safe_div, Medium, MediumInteraction};
use crate::sampler::SampleStream;
use crate::scene::Scene;
use crate::shape::SurfaceInteraction;
use crate::spectrum::{Mode, Spectrum};
use glam::Vec4;

#[derive(Clone, Debug)]
pub struct VolPathMisIntegrator {
    /// Longest path, in scattering events; `u32::MAX` for unbounded.
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
    /// Mitsuba's `use_spectral_mis`.
    pub spectral_mis: bool,
}

/// The ratios p / f a path carries (Mitsuba's `WeightMatrix` and its `update_weights` /
/// `mis_weight`).
trait MisWeights: Copy {
    fn ones() -> Self;
    /// Multiplies in one event of densities `p` (per channel) and contributions `f`.
    fn update(&mut self, p: Spectrum, f: Spectrum, channel: usize);
    /// The estimate's weight per channel, f / p (balance heuristic over the channels).
    fn weight(&self) -> Spectrum;
    /// The weight against a second strategy's ratios (balance heuristic over both).
    fn weight2(&self, other: &Self) -> Spectrum;
    /// A shadow ray with these unidirectional and NEE ratios can contribute nothing more.
    fn shadow_dead(uni: &Self, nee: &Self) -> bool;
}

fn finite_or_zero(v: Spectrum) -> Spectrum {
    let f = |x: f32| if x.is_finite() { x } else { 0.0 };
    Spectrum::new(f(v.x), f(v.y), f(v.z), f(v.w))
}

/// Spectral MIS over `N` channels (3 in RGB mode, 4 wavelengths in spectral mode): row i
/// holds (p_j / f_i) over channels j < N. In RGB mode row 3 and every row's lane 3 are
/// carried along but never read: the weight's lane 3 is lane 1's, green's copy.
#[derive(Clone, Copy)]
struct SpectralMis<const N: usize>([Spectrum; 4]);

impl<const N: usize> MisWeights for SpectralMis<N> {
    fn ones() -> Self {
        SpectralMis([Spectrum::ONE; 4])
    }
    #[inline]
    fn update(&mut self, p: Spectrum, f: Spectrum, _channel: usize) {
        for i in 0..N {
            let r = finite_or_zero(p / f[i]) * self.0[i];
            let nan0 = |x: f32| if x.is_nan() { 0.0 } else { x };
            self.0[i] = Spectrum::new(nan0(r.x), nan0(r.y), nan0(r.z), nan0(r.w));
        }
    }
    #[inline]
    fn weight(&self) -> Spectrum {
        let w = |row: Spectrum| {
            let s = if N == 3 {
                row.x + row.y + row.z
            } else {
                row.x + row.y + row.z + row.w
            };
            if s == 0.0 {
                0.0
            } else {
                N as f32 / s
            }
        };
        let g = w(self.0[1]);
        Spectrum::new(
            w(self.0[0]),
            g,
            w(self.0[2]),
            if N == 3 { g } else { w(self.0[3]) },
        )
    }
    #[inline]
    fn weight2(&self, o: &Self) -> Spectrum {
        SpectralMis::<N>(std::array::from_fn(|i| self.0[i] + o.0[i])).weight()
    }
    fn shadow_dead(uni: &Self, _nee: &Self) -> bool {
        uni.weight() == Spectrum::ZERO
    }
}

/// Without spectral MIS: (p_channel / f_i) per channel i.
#[derive(Clone, Copy)]
struct HeroMis(Spectrum);

impl MisWeights for HeroMis {
    fn ones() -> Self {
        HeroMis(Spectrum::ONE)
    }
    #[inline]
    fn update(&mut self, p: Spectrum, f: Spectrum, channel: usize) {
        self.0 = finite_or_zero(self.0 * (p[channel] / f));
    }
    #[inline]
    fn weight(&self) -> Spectrum {
        if self.0.abs().min_element() == 0.0 {
            Spectrum::ZERO
        } else {
            self.0.recip()
        }
    }
    #[inline]
    fn weight2(&self, o: &Self) -> Spectrum {
        HeroMis(self.0 + o.0).weight()
    }
    fn shadow_dead(uni: &Self, nee: &Self) -> bool {
        uni.0 == Spectrum::ZERO && nee.0 == Spectrum::ZERO
    }
}

/// The two strategies' ratios along a shadow ray.
struct ShadowMis<W> {
    nee: W,
    uni: W,
    mode: Mode,
}

impl<W: MisWeights> ShadowWeights for ShadowMis<W> {
    #[inline]
    fn segment(&mut self, tr: Spectrum, pdf: Spectrum, channel: usize) {
        self.nee.update(pdf, tr, channel);
        self.uni.update(pdf, tr, channel);
    }
    #[inline]
    fn collision(&mut self, mi: &MediumInteraction, channel: usize) {
        self.nee.update(Spectrum::ONE, mi.sigma_n, channel);
        let p_null = mean(safe_div(mi.sigma_n, mi.combined_extinction), self.mode);
        self.uni
            .update(Spectrum::splat(p_null), mi.sigma_n, channel);
    }
    #[inline]
    fn surface(&mut self, t: Spectrum, channel: usize) {
        self.nee.update(Spectrum::ONE, t, channel);
        self.uni.update(Spectrum::ONE, t, channel);
    }
    #[inline]
    fn is_zero(&self) -> bool {
        W::shadow_dead(&self.uni, &self.nee)
    }
}

impl VolPathMisIntegrator {
    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        match (self.spectral_mis, scene.mode) {
            (true, Mode::Rgb) => self.li_with::<SpectralMis<3>>(scene, ray, wl, sampler, stats),
            (true, Mode::Spectral) => {
                self.li_with::<SpectralMis<4>>(scene, ray, wl, sampler, stats)
            }
            (false, _) => self.li_with::<HeroMis>(scene, ray, wl, sampler, stats),
        }
    }

    /// Next-event estimation from `from`: the NEE and unidirectional ratios at the emitter
    /// (the path's `p_over_f` extended by the shadow ray), the emitted radiance and the sample.
    #[allow(clippy::too_many_arguments)]
    fn sample_emitter<W: MisWeights>(
        scene: &Scene,
        from: Vertex,
        medium: Option<u32>,
        p_over_f: W,
        channel: usize,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Option<(W, W, Spectrum, DirectionSample)> {
        let p = match from {
            Vertex::Surface(si) => si.p,
            Vertex::Medium(p) => p,
        };
        let ds = scene.sample_emitter_direction_at(p, sampler.next_2d(), wl)?;
        if ds.pdf.is_nan() || ds.pdf <= 0.0 {
            return None;
        }
        let mut w = ShadowMis {
            nee: p_over_f,
            uni: p_over_f,
            mode: scene.mode,
        };
        w.nee
            .update(Spectrum::splat(ds.pdf), Spectrum::ONE, channel);
        trace_shadow(
            scene, from, &ds, medium, channel, wl, sampler, stats, &mut w,
        );
        Some((w.nee, w.uni, ds.radiance, ds))
    }

    fn li_with<W: MisWeights>(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        let mode = scene.mode;
        let mut ray = Ray::new(ray.o, ray.d.normalize(), ray.tmax);
        let mut result = Spectrum::ZERO;
        let mut eta = 1.0f32;
        let mut depth = 0u32;
        let mut medium = scene.camera_medium;
        let mut specular_chain = !self.hide_emitters;
        let mut p_over_f = W::ones();
        let mut p_over_f_nee = W::ones();
        let channel = pick_channel(sampler.next_1d(), mode);
        let mut hit: Option<Option<SurfaceInteraction>> = None;
        let mut last_scatter_p = ray.o;
        let mut last_event_was_null = false;
        // Filled in place at surface vertices whose material varies (see `Scene::bsdf_at`).
        let mut bsdf_buf = ShadingBsdf::new();
        loop {
            // Russian roulette (not right after a null collision) and the depth limit.
            if !last_event_was_null && depth > self.rr_depth {
                let q = (p_over_f.weight().max_element() * eta * eta).min(0.95);
                if sampler.next_1d() >= q {
                    stats.rr_terminated += 1;
                    break;
                }
                p_over_f.update(Spectrum::splat(q), Spectrum::ONE, channel);
            }
            last_event_was_null = false;
            if depth >= self.max_depth || p_over_f.weight() == Spectrum::ZERO {
                break;
            }

            // Sampling the medium the ray travels in.
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
                p_over_f.update(pdf, tr, channel);
                p_over_f_nee.update(pdf, tr, channel);
                if mi.is_valid() {
                    let null_prob = mean(safe_div(mi.sigma_n, mi.combined_extinction), mode);
                    if sampler.next_1d() < null_prob {
                        last_event_was_null = true;
                        p_over_f.update(Spectrum::splat(null_prob), mi.sigma_n, channel);
                        p_over_f_nee.update(Spectrum::ONE, mi.sigma_n, channel);
                        pass_collision(&mut ray, &mut hit, &mi);
                        continue;
                    }
                    depth += 1;
                    if depth >= self.max_depth {
                        break;
                    }
                    stats.bounces += 1;
                    last_scatter_p = mi.p;
                    specular_chain = !med.sample_emitters;
                    p_over_f.update(Spectrum::splat(1.0 - null_prob), mi.sigma_s, channel);
                    if med.sample_emitters {
                        if let Some((mut nee_end, mut uni_end, emitted, ds)) = Self::sample_emitter(
                            scene,
                            Vertex::Medium(mi.p),
                            medium,
                            p_over_f,
                            channel,
                            wl,
                            sampler,
                            stats,
                        ) {
                            let phase_val = med.phase.eval(mi.wi, ds.d);
                            let pv = Spectrum::splat(phase_val);
                            nee_end.update(Spectrum::ONE, pv, channel);
                            let p = if ds.delta { 0.0 } else { phase_val };
                            uni_end.update(Spectrum::splat(p), pv, channel);
                            result += nee_end.weight2(&uni_end) * emitted;
                        }
                    }
                    p_over_f_nee = p_over_f;
                    let Some(ps) = med.phase.sample(mi.wi, sampler.next_2d()) else {
                        break;
                    };
                    let f = Spectrum::splat(ps.weight * ps.pdf);
                    p_over_f.update(Spectrum::splat(ps.pdf), f, channel);
                    p_over_f_nee.update(Spectrum::ONE, f, channel);
                    ray = Ray::new(mi.p, ps.wo, f32::INFINITY);
                    hit = None;
                    continue;
                }
            }

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
                        p_over_f.weight()
                    } else {
                        let pdf = emitter_pdf_at(scene, last_scatter_p, si.as_ref(), ray.d);
                        p_over_f_nee.update(Spectrum::splat(pdf), Spectrum::ONE, channel);
                        p_over_f.weight2(&p_over_f_nee)
                    };
                    result += w * le;
                }
            }
            let Some(si) = si else {
                break;
            };
            let bsdf = scene.bsdf_at(&si, wl, &mut bsdf_buf);
            let wi = si.frame.to_local(-ray.d);

            // Next-event estimation.
            if depth.saturating_add(1) < self.max_depth && bsdf.has_smooth_lobe(wi) {
                if let Some((mut nee_end, mut uni_end, emitted, ds)) = Self::sample_emitter(
                    scene,
                    Vertex::Surface(&si),
                    medium,
                    p_over_f,
                    channel,
                    wl,
                    sampler,
                    stats,
                ) {
                    let wo = si.frame.to_local(ds.d);
                    let f = bsdf.eval(wi, wo);
                    if f != Spectrum::ZERO {
                        nee_end.update(Spectrum::ONE, f, channel);
                        let p = if ds.delta { 0.0 } else { bsdf.pdf(wi, wo) };
                        uni_end.update(Spectrum::splat(p), f, channel);
                        result += nee_end.weight2(&uni_end) * emitted;
                    }
                }
            }

            // BSDF sampling.
            let u1 = sampler.next_1d();
            let u2 = sampler.next_2d();
            let Some(bs) = bsdf.sample(wi, u1, u2) else {
                break;
            };
            if bs.pdf.is_nan() || bs.pdf <= 0.0 {
                break;
            }
            eta *= bs.eta;
            let wo_world = si.frame.to_world(bs.wo).normalize();
            ray = Scene::spawn_ray(&si, wo_world);
            hit = None;
            let f = bs.weight * bs.pdf;
            if !bs.null {
                depth += 1;
                stats.bounces += 1;
                last_scatter_p = si.p;
                p_over_f_nee = p_over_f;
                if bs.delta {
                    specular_chain = true;
                }
            }
            if !bs.delta {
                specular_chain = false;
            }
            p_over_f.update(Spectrum::splat(bs.pdf), f, channel);
            if !bs.null {
                p_over_f_nee.update(Spectrum::ONE, f, channel);
            }
            if scene.is_medium_transition(&si) {
                medium = scene.target_medium(&si, ray.d);
            }
        }
        result
    }
}
