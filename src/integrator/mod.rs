//! Integrators: estimators of the radiance arriving along a camera ray.

pub mod path;

pub use path::PathIntegrator;

use crate::bsdf::Spectrum;
use crate::geometry::Ray;
use crate::sampler::SampleStream;
use crate::scene::Scene;

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
}

impl Integrator {
    #[inline]
    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        match self {
            Integrator::Path(p) => p.li(scene, ray, sampler, stats),
        }
    }
}
