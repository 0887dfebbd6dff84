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

impl PathIntegrator {
    pub fn li(
        &self,
        scene: &Scene,
        mut ray: Ray,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        let mut result = Spectrum::ZERO;
        if self.max_depth == 0 {
            return result;
        }
        let mut throughput = Spectrum::ONE;
        let mut eta = 1.0f32;
        let mut depth = 0u32;
        // The previous vertex and how the current ray was sampled, for the MIS weight of an
        // emitter hit. Camera rays count as delta-sampled: no MIS.
        let mut prev_p = ray.o;
        let mut prev_bsdf_pdf = 1.0f32;
        let mut prev_delta = true;
        // Filled in place at vertices whose material varies (see `Scene::bsdf_at`).
        let mut bsdf_buf = ShadingBsdf::new();
        loop {
            stats.rays += 1;
            let Some(si) = scene.intersect(&ray) else {
                // The ray leaves the scene: the environment's emission, MIS-weighted against
                // emitter sampling (camera rays and delta bounces: weight 1). With
                // hide_emitters, camera rays that miss see black, as in Mitsuba.
                if scene.environment.is_some() && !(depth == 0 && self.hide_emitters) {
                    let le = scene.eval_environment(ray.d);
                    if le != Vec3::ZERO {
                        let w = if prev_delta {
                            1.0
                        } else {
                            mis_power(prev_bsdf_pdf, scene.pdf_environment(ray.d))
                        };
                        result += throughput * le * w;
                    }
                }
                break;
            };
            let wi_world = -ray.d.normalize();
            let shape = &scene.shapes[si.shape as usize];
            if let Some(e) = shape.emitter {
                if depth == 0 && self.hide_emitters {
                    // Camera rays pass through directly visible emitters.
                    ray = Scene::spawn_ray(&si, ray.d);
                    continue;
                }
                let le = match &scene.emitters[e as usize] {
                    crate::emitter::Emitter::Area(area) => area.eval(&si, wi_world, &scene.shapes),
                    _ => Vec3::ZERO,
                };
                if le != Vec3::ZERO {
                    let w = if prev_delta {
                        1.0
                    } else {
                        mis_power(prev_bsdf_pdf, scene.pdf_emitter_direction(prev_p, &si))
                    };
                    result += throughput * le * w;
                }
            }
            if depth.saturating_add(1) >= self.max_depth {
                break;
            }
            stats.bounces += 1;
            let bsdf = scene.bsdf_at(&si, &mut bsdf_buf);
            let wi = si.frame.to_local(wi_world);

            // Next-event estimation.
            let u_light = sampler.next_2d();
            if bsdf.has_smooth_lobe(wi) {
                if let Some(e) = sample_emitter(scene, &si, bsdf, wi, u_light, stats) {
                    // Delta emitters cannot be found by BSDF sampling: no MIS.
                    let w = if e.delta {
                        1.0
                    } else {
                        mis_power(e.emitter_pdf, e.bsdf_pdf)
                    };
                    result += throughput * e.value * w;
                }
            }

            // BSDF sampling.
            let u1 = sampler.next_1d();
            let u2 = sampler.next_2d();
            let Some(bs) = bsdf.sample(wi, u1, u2) else {
                break;
            };
            let wo_world = si.frame.to_world(bs.wo);
            throughput *= bs.weight;
            eta *= bs.eta;
            prev_p = si.p;
            prev_bsdf_pdf = bs.pdf;
            prev_delta = bs.delta;
            ray = Scene::spawn_ray(&si, wo_world);
            depth += 1;

            // Russian roulette.
            let throughput_max = throughput.max_element();
            if throughput_max <= 0.0 || !throughput_max.is_finite() {
                break;
            }
            if depth >= self.rr_depth {
                let q = (throughput_max * eta * eta).min(0.95);
                if sampler.next_1d() >= q {
                    stats.rr_terminated += 1;
                    break;
                }
                throughput /= q;
            }
        }
        result
    }
}
