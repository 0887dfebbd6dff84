//! The integrator built from its description, once, in one place: the scene is built first
//! (without knowing which integrator walks it), then the integrator is made for it.

use super::{
    aov::AovIntegrator, ptracer, radiosity::RadiosityIntegrator, Bdpt, DirectIntegrator,
    Integrator, ParticleTracer, PathIntegrator, Sppm, VolPathIntegrator, VolPathMisIntegrator,
    WhittedIntegrator,
};
use crate::error::{Error, Result};
use crate::scene::description::IntegratorDesc;
use crate::scene::Scene;

/// A description's `max_depth` (−1: unbounded) as the integrators count it.
fn depth(max_depth: i64) -> u32 {
    if max_depth < 0 {
        u32::MAX
    } else {
        max_depth.min(u32::MAX as i64) as u32
    }
}

/// A description's `rr_depth` (> 0 once read) as the integrators count it.
fn rr(rr_depth: i64) -> u32 {
    rr_depth.clamp(1, u32::MAX as i64) as u32
}

impl Integrator {
    /// The integrator `desc` describes, for `scene` (radiosity divides it into patches; the
    /// light tracers check its camera and media; SPPM's automatic photon count is its pixel
    /// count).
    pub fn build(desc: &IntegratorDesc, scene: &Scene) -> Result<Integrator> {
        Self::build_in(desc, scene, false)
    }

    fn build_in(desc: &IntegratorDesc, scene: &Scene, nested: bool) -> Result<Integrator> {
        let has_media = !scene.media.is_empty();
        Ok(match desc.clone() {
            IntegratorDesc::VolPath {
                mis,
                max_depth,
                rr_depth,
                hide_emitters,
                use_spectral_mis,
            } => {
                let (max_depth, rr_depth) = (depth(max_depth), rr(rr_depth));
                if mis {
                    Integrator::VolPathMis(VolPathMisIntegrator {
                        max_depth,
                        rr_depth,
                        hide_emitters,
                        spectral_mis: use_spectral_mis,
                    })
                } else {
                    Integrator::VolPath(VolPathIntegrator {
                        max_depth,
                        rr_depth,
                        hide_emitters,
                    })
                }
            }
            IntegratorDesc::Path {
                max_depth,
                rr_depth,
                hide_emitters,
            } => Integrator::Path(PathIntegrator {
                max_depth: depth(max_depth),
                rr_depth: rr(rr_depth),
                hide_emitters,
            }),
            IntegratorDesc::Aov { aovs, nested } => {
                let nested = nested
                    .iter()
                    .map(|(name, n)| Ok((name.clone(), Self::build_in(n, scene, true)?)))
                    .collect::<Result<Vec<_>>>()?;
                Integrator::Aov(AovIntegrator {
                    aovs,
                    nested,
                    world_origin: scene.world_origin,
                    group: 0,
                })
            }
            IntegratorDesc::Whitted {
                max_depth,
                emitter_samples,
                hide_emitters,
                shadows,
            } => Integrator::Whitted(WhittedIntegrator {
                max_depth,
                emitter_samples,
                hide_emitters,
                shadows,
            }),
            IntegratorDesc::Radiosity(params) => {
                if nested {
                    return Err(Error::Invalid(
                        "radiosity cannot be nested in an aov integrator".into(),
                    ));
                }
                Integrator::Radiosity(RadiosityIntegrator::new(scene, params)?)
            }
            IntegratorDesc::Direct {
                emitter_samples,
                bsdf_samples,
                hide_emitters,
            } => Integrator::Direct(DirectIntegrator::new(
                emitter_samples,
                bsdf_samples,
                hide_emitters,
            )),
            IntegratorDesc::Sppm {
                max_depth,
                photon_count,
                initial_radius,
                alpha,
            } => {
                ptracer::check_scene("sppm", false, &scene.camera, has_media)?;
                Integrator::Sppm(Sppm {
                    max_depth: depth(max_depth),
                    photon_count: if photon_count == 0 {
                        (scene.width * scene.height) as u64
                    } else {
                        photon_count
                    },
                    initial_radius: initial_radius as f32,
                    alpha: alpha as f32,
                })
            }
            IntegratorDesc::Bdpt {
                max_depth,
                rr_depth,
                hide_emitters,
                strategy,
                strategy_mis,
                light_paths,
            } => {
                ptracer::check_scene("bdpt", false, &scene.camera, has_media)?;
                Integrator::Bdpt(Bdpt {
                    max_depth: depth(max_depth),
                    rr_depth: rr(rr_depth),
                    hide_emitters,
                    strategy,
                    strategy_mis,
                    // A strategy rendered alone is a debugging image: every sample traces
                    // both subpaths.
                    light_paths: match strategy {
                        Some(_) => Some(light_paths.unwrap_or(1.0) as f32),
                        None => light_paths.map(|x| x as f32),
                    },
                    pilot_choices: Default::default(),
                    shadow_roulette: true,
                })
            }
            IntegratorDesc::ParticleTracer {
                max_depth,
                rr_depth,
                hide_emitters,
                samples_per_pass,
            } => {
                ptracer::check_scene("ptracer", true, &scene.camera, has_media)?;
                Integrator::ParticleTracer(ParticleTracer {
                    max_depth: depth(max_depth),
                    rr_depth: rr(rr_depth),
                    hide_emitters,
                    samples_per_pass: (samples_per_pass > 0).then_some(samples_per_pass),
                })
            }
        })
    }
}
