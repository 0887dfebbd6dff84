//! Emitters. Sampling returns solid-angle densities so that next-event estimation and the MIS
//! weight of a BSDF-sampled hit use one and the same pdf.

pub mod area;

pub use area::AreaEmitter;

use crate::bsdf::Spectrum;
use crate::shape::Shape;
use glam::{Vec2, Vec3};

/// A direction towards a sampled point on an emitter, as seen from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct DirectionSample {
    /// The sampled point on the emitter, its error bound and unit normal.
    pub p: Vec3,
    pub p_error: Vec3,
    pub n: Vec3,
    /// Unit direction from the reference point to `p`.
    pub d: Vec3,
    /// Distance from the reference point to `p`.
    pub dist: f32,
    /// Solid-angle density (including the probability of choosing this emitter once the
    /// scene has set it).
    pub pdf: f32,
    /// Emitted radiance towards the reference point.
    pub radiance: Spectrum,
}

#[derive(Clone, Debug)]
pub enum Emitter {
    Area(AreaEmitter),
}

impl Emitter {
    pub fn sample_direction(
        &self,
        p_ref: Vec3,
        u: Vec2,
        shapes: &[Shape],
    ) -> Option<DirectionSample> {
        match self {
            Emitter::Area(e) => e.sample_direction(p_ref, u, shapes),
        }
    }
}
