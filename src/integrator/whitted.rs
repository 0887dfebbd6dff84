//! `whitted`: classic recursive ray tracing (Whitted 1980, "An Improved Illumination Model
//! for Shaded Display"), penumbra's own (Mitsuba 3 has none). At every surface a ray hits:
//!
//! - the emission of an area light hit (directly, or through mirror and glass);
//! - direct light from **every** emitter through shadow rays: point, spot and directional
//!   lights exactly with one ray each, area lights and environments with `emitter_samples`
//!   samples each (averaged), weighted by the surface's full non-delta BSDF (so glossy
//!   highlights appear; a Phong or diffuse surface is the classic case);
//! - perfect mirror reflection and refraction traced recursively, each branch weighted by
//!   its share of the BSDF: at a dielectric both the Fresnel-reflected and the refracted ray
//!   are followed (F and 1 − F), at a conductor the reflection, at plastic its specular
//!   reflection, at a thin dielectric both of its delta lobes.
//!
//! No indirect diffuse light: the method is biased wherever light reaches a non-delta surface
//! after bouncing off another non-delta one (or via a mirror: caustics), and exact where all
//! light paths are "direct light, then delta bounces to the camera" — which
//! `tests/whitted.rs` checks against the path tracer. With only delta lights and perfect
//! specular surfaces the only randomness left is the pixel position.
//!
//! With `shadows` false (default true) no shadow ray is traced: every emitter lights every
//! surface facing it, as in plain ray casting with local shading.
//!
//! Depth counts path segments as in Mitsuba's `path`: `max_depth` 1 shows emitters seen
//! directly, 2 adds direct light at the first surface, each mirror or refraction bounce one
//! more. Default 6, at most 20 (every glass interface doubles the rays). Delta lobes of
//! composite BSDFs (`mask`, `blendbsdf`, normal and bump maps) are followed by one sampled
//! branch instead of all of them: unbiased, but noisy.

use crate::bsdf::{BsdfSample, Spectrum};
use crate::geometry::Ray;
use crate::integrator::{connect_emitter, pass_through_emitters, PathStats};
use crate::material::shading::Node;
use crate::material::ShadingBsdf;
use crate::sampler::SampleStream;
use crate::scene::Scene;
use crate::spectrum::NO_WAVELENGTHS;
use arrayvec::ArrayVec;
use glam::{Vec2, Vec3};

/// The largest `max_depth` accepted.
pub use crate::scene::description::WHITTED_MAX_DEPTH as MAX_DEPTH;

#[derive(Clone, Debug)]
pub struct WhittedIntegrator {
    pub max_depth: u32,
    /// Samples per area emitter (and environment) at each shading point.
    pub emitter_samples: u32,
    pub hide_emitters: bool,
    /// Shadow rays towards the emitters; without them (`shadows` false) every emitter
    /// lights every surface facing it: the ladder's "ray casting only".
    pub shadows: bool,
}

/// A ray still to trace: its weight and the depth of the vertex it will hit.
struct Branch {
    ray: Ray,
    weight: Spectrum,
    depth: u32,
}

/// The delta lobes of a BSDF at `wi`, each with its share of the BSDF (the lobe's selection
/// probability times its sample weight): every lobe of a plain BSDF, or of a two-sided one;
/// `None` for composite BSDFs, whose lobes are sampled instead.
fn delta_lobes(bsdf: &ShadingBsdf, wi: Vec3) -> Option<ArrayVec<(Vec3, Spectrum), 2>> {
    let (leaf, flip) = match bsdf.node(0) {
        Node::Leaf(b) => (b, false),
        Node::TwoSided { front, back } => {
            let (i, flip) = if wi.z >= 0.0 {
                (*front, false)
            } else {
                (*back, true)
            };
            match bsdf.node(i) {
                Node::Leaf(b) => (b, flip),
                _ => return None,
            }
        }
        _ => return None,
    };
    let f = |v: Vec3| if flip { Vec3::new(v.x, v.y, -v.z) } else { v };
    let wi_local = f(wi);
    let mut out = ArrayVec::new();
    // Every plain BSDF picks among at most two delta lobes by u1 (the first below its
    // probability, the second above), reporting the lobe's probability as `pdf` (1 for a
    // conductor's single lobe).
    let probe = |u1: f32| -> Option<BsdfSample> {
        let s = leaf.sample(wi_local, u1, Vec2::splat(0.5))?;
        s.delta.then_some(s)
    };
    let first = probe(0.0);
    let second = probe(1.0 - f32::EPSILON);
    for s in [first, second].into_iter().flatten() {
        if out.iter().any(|(wo, _)| *wo == f(s.wo)) {
            continue; // a BSDF with one delta lobe (a conductor) returns it for both probes
        }
        out.push((f(s.wo), s.weight * s.pdf));
    }
    Some(out)
}

impl WhittedIntegrator {
    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        let mut result = Spectrum::ZERO;
        if self.max_depth == 0 {
            return result;
        }
        let mut stack: ArrayVec<Branch, 48> = ArrayVec::new();
        stack.push(Branch {
            ray,
            weight: Spectrum::ONE,
            depth: 1,
        });
        while let Some(Branch { ray, weight, depth }) = stack.pop() {
            stats.rays += 1;
            let mut hit = scene.intersect(&ray);
            if depth == 1 && self.hide_emitters {
                // Camera rays pass through area emitters; the environment stays hidden.
                hit = pass_through_emitters(scene, ray.d, hit, stats);
            } else {
                result += weight
                    * crate::integrator::emission_at(scene, hit.as_ref(), ray.d, NO_WAVELENGTHS);
            }
            let Some(si) = hit else {
                continue;
            };
            if depth >= self.max_depth {
                continue;
            }
            stats.bounces += 1;
            let bsdf = scene.shading_bsdf(&si, NO_WAVELENGTHS);
            let wi = si.frame.to_local(-ray.d.normalize());

            // Direct light from every emitter.
            if bsdf.has_smooth_lobe(wi) {
                for emitter in &scene.emitters {
                    let n = if emitter.is_delta() {
                        1
                    } else {
                        self.emitter_samples
                    };
                    let mut sum = Spectrum::ZERO;
                    for _ in 0..n {
                        let u = sampler.next_2d();
                        let Some(ds) =
                            emitter.sample_direction(si.p, u, &scene.shapes, NO_WAVELENGTHS)
                        else {
                            continue;
                        };
                        if ds.pdf.is_nan() || ds.pdf <= 0.0 {
                            continue;
                        }
                        if !self.shadows {
                            sum += bsdf.eval(wi, si.frame.to_local(ds.d)) * ds.radiance / ds.pdf;
                        } else if let Some(e) = connect_emitter(scene, &si, &bsdf, wi, &ds, stats) {
                            sum += e.value;
                        }
                    }
                    result += weight * sum / n as f32;
                }
            }

            // Perfect reflection and refraction, recursively.
            match delta_lobes(&bsdf, wi) {
                Some(lobes) => {
                    for (wo, share) in lobes {
                        let w = weight * share;
                        if w == Spectrum::ZERO || stack.is_full() {
                            continue;
                        }
                        stack.push(Branch {
                            ray: Scene::spawn_ray(&si, si.frame.to_world(wo)),
                            weight: w,
                            depth: depth + 1,
                        });
                    }
                }
                None => {
                    let (u1, u2) = (sampler.next_1d(), sampler.next_2d());
                    if let Some(bs) = bsdf.sample(wi, u1, u2) {
                        if bs.delta && !stack.is_full() {
                            stack.push(Branch {
                                ray: Scene::spawn_ray(&si, si.frame.to_world(bs.wo)),
                                weight: weight * bs.weight,
                                depth: depth + 1,
                            });
                        }
                    }
                }
            }
        }
        result
    }
}
