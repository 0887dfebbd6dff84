//! Mitsuba's `path` integrator: unidirectional path tracing with next-event estimation at
//! every non-delta vertex, BSDF importance sampling, and both combined by multiple importance
//! sampling with the power heuristic (Veach and Guibas 1995; Veach 1997, ch. 9), plus Russian
//! roulette from `rr_depth` on.
//!
//! Depth semantics follow Mitsuba exactly: `max_depth` counts path segments, so 1 renders only
//! emitters seen directly and 2 adds direct lighting; Russian roulette applies once depth ≥
//! `rr_depth`, continuing with probability q = min(max(throughput) · η², 0.95).

use crate::geometry::Ray;
use crate::integrator::{sample_emitter, PathStats};
use crate::material::ShadingBsdf;
use crate::sampler::SampleStream;
use crate::sampling::mis_power;
use crate::scene::Scene;
use crate::shape::SurfaceInteraction;
use crate::spectrum::Spectrum;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct PathIntegrator {
    /// Longest path, in segments; `u32::MAX` for unbounded.
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Directly visible emitters are not shown (camera rays pass through area lights).
    pub hide_emitters: bool,
}

// The per-vertex functions are `#[inline(always)]`: used by both engines, they are no
// longer inlined into `li` by LLVM's own choice, which cost the scalar engine 2.9% more
// instructions (callgrind, Cornell box 32x32, 8 spp).

/// One path between two bounces: what the loop of [`PathIntegrator::li`] carries from one
/// vertex to the next. The lane engine (`integrator::lanes::path`) keeps the same fields in
/// lanes and calls the same per-vertex functions below, so both engines compute the same
/// numbers.
#[derive(Clone, Copy, Debug)]
pub struct PathState {
    /// The ray to trace next.
    pub ray: Ray,
    pub throughput: Spectrum,
    pub result: Spectrum,
    pub eta: f32,
    /// Segments traced so far (0 for the camera ray).
    pub depth: u32,
    /// The previous vertex and how the current ray was sampled, for the MIS weight of an
    /// emitter hit. Camera rays count as delta-sampled: no MIS.
    pub prev_p: Vec3,
    pub prev_bsdf_pdf: f32,
    pub prev_delta: bool,
}

/// What a path does after the emission at a surface hit ([`PathIntegrator::at_surface`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SurfaceStep {
    /// The path ends here.
    End,
    /// Trace the state's ray again (a camera ray passing through a hidden emitter).
    Trace,
    /// Scatter at the hit ([`PathIntegrator::scatter`]), with the direction towards the
    /// previous vertex (world space, unit).
    Scatter { wi_world: Vec3 },
}

impl PathIntegrator {
    /// One path per camera ray: the loop of trace, [`PathIntegrator::at_surface`] (or
    /// [`PathIntegrator::escape`]) and [`PathIntegrator::scatter`].
    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        let Some(mut st) = self.start(ray) else {
            return Spectrum::ZERO;
        };
        // Filled in place at vertices whose material varies (see `Scene::bsdf_at`).
        let mut bsdf_buf = ShadingBsdf::new();
        loop {
            stats.rays += 1;
            let Some(si) = scene.intersect(&st.ray) else {
                self.escape(scene, &mut st);
                break;
            };
            match self.at_surface(scene, &mut st, &si) {
                SurfaceStep::End => break,
                SurfaceStep::Trace => continue,
                SurfaceStep::Scatter { wi_world } => {
                    if !self.scatter(scene, &mut st, &si, wi_world, sampler, stats, &mut bsdf_buf) {
                        break;
                    }
                }
            }
        }
        st.result
    }

    /// The state of a path whose camera ray is `ray`; `None` when `max_depth` is 0 (the path
    /// is black).
    #[inline(always)]
    pub fn start(&self, ray: Ray) -> Option<PathState> {
        if self.max_depth == 0 {
            return None;
        }
        Some(PathState {
            ray,
            throughput: Spectrum::ONE,
            result: Spectrum::ZERO,
            eta: 1.0,
            depth: 0,
            prev_p: ray.o,
            prev_bsdf_pdf: 1.0,
            prev_delta: true,
        })
    }

    /// The state's ray left the scene: the environment's emission, MIS-weighted against
    /// emitter sampling (camera rays and delta bounces: weight 1). With hide_emitters,
    /// camera rays that miss see black, as in Mitsuba. The path ends.
    #[inline(always)]
    pub fn escape(&self, scene: &Scene, st: &mut PathState) {
        if scene.environment.is_some() && !(st.depth == 0 && self.hide_emitters) {
            let le = scene.eval_environment(st.ray.d);
            if le != Vec3::ZERO {
                let w = if st.prev_delta {
                    1.0
                } else {
                    mis_power(st.prev_bsdf_pdf, scene.pdf_environment(st.ray.d))
                };
                st.result += st.throughput * le * w;
            }
        }
    }

    /// The state's ray hit `si`: its emission (MIS-weighted against emitter sampling), and
    /// whether the path goes on.
    #[inline(always)]
    pub fn at_surface(
        &self,
        scene: &Scene,
        st: &mut PathState,
        si: &SurfaceInteraction,
    ) -> SurfaceStep {
        let wi_world = -st.ray.d.normalize();
        let shape = &scene.shapes[si.shape as usize];
        if let Some(e) = shape.emitter {
            if st.depth == 0 && self.hide_emitters {
                // Camera rays pass through directly visible emitters.
                st.ray = Scene::spawn_ray(si, st.ray.d);
                return SurfaceStep::Trace;
            }
            let le = match &scene.emitters[e as usize] {
                crate::emitter::Emitter::Area(area) => area.eval(si, wi_world, &scene.shapes),
                _ => Vec3::ZERO,
            };
            if le != Vec3::ZERO {
                let w = if st.prev_delta {
                    1.0
                } else {
                    mis_power(st.prev_bsdf_pdf, scene.pdf_emitter_direction(st.prev_p, si))
                };
                st.result += st.throughput * le * w;
            }
        }
        if st.depth.saturating_add(1) >= self.max_depth {
            return SurfaceStep::End;
        }
        SurfaceStep::Scatter { wi_world }
    }

    /// The vertex at `si`: next-event estimation, BSDF sampling of the next ray and Russian
    /// roulette; false when the path ends. `bsdf_buf` holds the BSDF where the material
    /// varies.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn scatter(
        &self,
        scene: &Scene,
        st: &mut PathState,
        si: &SurfaceInteraction,
        wi_world: Vec3,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
        bsdf_buf: &mut ShadingBsdf,
    ) -> bool {
        stats.bounces += 1;
        let bsdf = scene.bsdf_at(si, bsdf_buf);
        let wi = si.frame.to_local(wi_world);
        self.next_event(scene, st, si, bsdf, wi, sampler, stats);
        self.sample_bsdf(st, si, bsdf, wi, sampler) && self.roulette(st, sampler, stats)
    }

    /// Next-event estimation at `si`: one emitter sample, MIS-weighted against BSDF
    /// sampling, added to the result.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn next_event(
        &self,
        scene: &Scene,
        st: &mut PathState,
        si: &SurfaceInteraction,
        bsdf: &ShadingBsdf,
        wi: Vec3,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) {
        let u_light = sampler.next_2d();
        if bsdf.has_smooth_lobe(wi) {
            if let Some(e) = sample_emitter(scene, si, bsdf, wi, u_light, stats) {
                // Delta emitters cannot be found by BSDF sampling: no MIS.
                let w = if e.delta {
                    1.0
                } else {
                    mis_power(e.emitter_pdf, e.bsdf_pdf)
                };
                st.result += st.throughput * e.value * w;
            }
        }
    }

    /// BSDF sampling: the next ray, its throughput and MIS state; false when the BSDF
    /// gives no direction.
    #[inline(always)]
    pub fn sample_bsdf(
        &self,
        st: &mut PathState,
        si: &SurfaceInteraction,
        bsdf: &ShadingBsdf,
        wi: Vec3,
        sampler: &mut SampleStream,
    ) -> bool {
        let u1 = sampler.next_1d();
        let u2 = sampler.next_2d();
        let Some(bs) = bsdf.sample(wi, u1, u2) else {
            return false;
        };
        let wo_world = si.frame.to_world(bs.wo);
        st.throughput *= bs.weight;
        st.eta *= bs.eta;
        st.prev_p = si.p;
        st.prev_bsdf_pdf = bs.pdf;
        st.prev_delta = bs.delta;
        st.ray = Scene::spawn_ray(si, wo_world);
        st.depth += 1;
        true
    }

    /// Russian roulette after a bounce: false when the path ends (no throughput left, or
    /// terminated from `rr_depth` on).
    #[inline(always)]
    pub fn roulette(
        &self,
        st: &mut PathState,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> bool {
        let throughput_max = st.throughput.max_element();
        if throughput_max <= 0.0 || !throughput_max.is_finite() {
            return false;
        }
        if st.depth >= self.rr_depth {
            let q = (throughput_max * st.eta * st.eta).min(0.95);
            if sampler.next_1d() >= q {
                stats.rr_terminated += 1;
                return false;
            }
            st.throughput /= q;
        }
        true
    }
}
