//! The lane engine (issue 42): paths side by side in the lanes of a [`crate::simd::Lanes`]
//! backend, per thread and per tile, with their state in structure-of-arrays form; lanes
//! whose path ended are refilled from the tile's queue of (pixel, sample) pairs before the
//! next bounce. It covers the `path` integrator ([`path`]); the render driver runs every
//! other integrator on the scalar engine and says so.
//!
//! **Same image as the scalar engine, bit for bit.** A sample's numbers depend only on
//! (seed, pixel, sample index, dimension): each lane draws from its own sample stream, and
//! the per-vertex steps are the scalar integrator's own functions
//! ([`crate::integrator::path::PathIntegrator::at_surface`], `scatter`, ...). Paths end out
//! of order, so each tile's results are kept per sample and added to the film in the scalar
//! engine's order when the tile is done (pixel by pixel, samples ascending).
//!
//! Kernels are ported one at a time (the design note's step 3): the scatter step
//! ([`crate::integrator::path::PathIntegrator::scatter_lanes`]) runs emitter sampling, the
//! shadow rays, the ray-origin offsets, MIS and the roulette's arithmetic as lane kernels,
//! written once over [`crate::simd::Lanes`], whose width-1 instance is the scalar engine's
//! code, and so are the step from a hit on a shape that does not emit to the scatter step
//! and the `independent` sampler's draws (every lane's PCG32 in u64 lanes,
//! [`crate::sampler::pcg`]). The rest (the traversal, emission, the BSDFs other than
//! `diffuse`, the other samplers' draws) is still the scalar code, called lane by lane.

pub mod path;

use crate::simd::MAX_WIDTH;

/// How full the lanes were: counters of the lane engine, summed over a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LaneStats {
    /// Lanes per packet (0 when the lane engine did not run).
    pub width: u64,
    /// Packet iterations: one bounce of every active lane each.
    pub iterations: u64,
    /// Active lanes at the intersection step, summed over iterations.
    pub traced: u64,
    /// Lanes that went on to scatter (next-event estimation and BSDF sampling), summed over
    /// iterations.
    pub scattered: u64,
    /// Iterations by the number of lanes active at their intersection step (0 to 16).
    pub by_active: [u64; MAX_WIDTH + 1],
    /// Active lanes at the intersection step by the depth of their path (segments traced
    /// before: 0 for camera rays; the last entry counts that depth and deeper).
    pub by_depth: [u64; LaneStats::DEPTHS],
}

impl LaneStats {
    /// Depths counted separately in [`LaneStats::by_depth`].
    pub const DEPTHS: usize = 8;

    /// Active lanes over lanes at the intersection step (0 when nothing ran).
    pub fn utilisation(&self) -> f64 {
        self.traced as f64 / (self.iterations * self.width).max(1) as f64
    }

    /// Lanes scattering over lanes at the scatter step.
    pub fn scatter_utilisation(&self) -> f64 {
        self.scattered as f64 / (self.iterations * self.width).max(1) as f64
    }
}

impl std::ops::AddAssign for LaneStats {
    fn add_assign(&mut self, o: Self) {
        self.width = self.width.max(o.width);
        self.iterations += o.iterations;
        self.traced += o.traced;
        self.scattered += o.scattered;
        for (a, b) in self.by_active.iter_mut().zip(o.by_active) {
            *a += b;
        }
        for (a, b) in self.by_depth.iter_mut().zip(o.by_depth) {
            *a += b;
        }
    }
}
