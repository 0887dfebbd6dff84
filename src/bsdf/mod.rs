//! BSDFs in Mitsuba 3's conventions: directions in the local shading frame (z = normal),
//! `wi` points to where the light goes (towards the camera along the path), `wo` to where it
//! comes from; `eval` includes the cosine foreshortening |cos θo|, and `sample` returns the
//! weight eval / pdf. Closed set of models, dispatched by `match`.

pub mod diffuse;
pub mod twosided;

pub use diffuse::Diffuse;
pub use twosided::TwoSided;

use glam::{Vec2, Vec3};

/// An RGB triple of linear sRGB-primaries values.
pub type Spectrum = Vec3;

/// A direction sampled from a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled direction (local frame).
    pub wo: Vec3,
    /// Solid-angle density of `wo` (meaningless for delta lobes).
    pub pdf: f32,
    /// eval(wi, wo) / pdf.
    pub weight: Spectrum,
    /// Relative index of refraction along the sampled direction (1 for reflection).
    pub eta: f32,
    /// The sampled lobe is a Dirac delta.
    pub delta: bool,
}

#[derive(Clone, Debug)]
pub enum Bsdf {
    Diffuse(Diffuse),
    TwoSided(TwoSided),
}

impl Bsdf {
    /// f(wi, wo) |cos θo|.
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        match self {
            Bsdf::Diffuse(b) => b.eval(wi, wo),
            Bsdf::TwoSided(b) => b.eval(wi, wo),
        }
    }

    /// Solid-angle density with which `sample` produces `wo`.
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        match self {
            Bsdf::Diffuse(b) => b.pdf(wi, wo),
            Bsdf::TwoSided(b) => b.pdf(wi, wo),
        }
    }

    /// Samples an outgoing direction; `u1` picks a lobe, `u2` the direction.
    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        match self {
            Bsdf::Diffuse(b) => b.sample(wi, u2),
            Bsdf::TwoSided(b) => b.sample(wi, u1, u2),
        }
    }

    /// Whether the BSDF has a non-delta lobe on the side `wi` lies on: only then does
    /// emitter sampling (NEE) make sense.
    pub fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        match self {
            Bsdf::Diffuse(_) => true,
            Bsdf::TwoSided(b) => b.side(wi).has_smooth_lobe(wi),
        }
    }
}
