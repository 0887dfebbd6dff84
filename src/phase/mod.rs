//! Phase functions: the angular distribution of light scattered inside a medium (Mitsuba's
//! `phase` plugins). One file per plugin; this enum dispatches.
//!
//! Convention (Mitsuba's): `wi` points back along the incoming ray (`wi = −ray.d`), `wo` away
//! from the scattering point, both unit world-space vectors. `eval` returns the phase function
//! value p(wi, wo) (a density over the sphere: ∫ p dwo = 1, no cosine); sampling returns a
//! direction, its weight p / pdf (1: both plugins sample exactly) and its density.
//!
//! | plugin | file | parameters |
//! |---|---|---|
//! | `isotropic` | [`isotropic`] | none |
//! | `hg` | [`hg`] | `g` ∈ (−1, 1), default 0.8 |

pub mod hg;
pub mod isotropic;

pub use hg::HenyeyGreenstein;

use glam::{Vec2, Vec3};

/// A direction sampled from a phase function.
#[derive(Clone, Copy, Debug)]
pub struct PhaseSample {
    pub wo: Vec3,
    /// p(wi, wo) / pdf.
    pub weight: f32,
    /// Solid-angle density of `wo`.
    pub pdf: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhaseFunction {
    Isotropic,
    HenyeyGreenstein(HenyeyGreenstein),
}

impl PhaseFunction {
    /// p(wi, wo), which is also the density with which [`PhaseFunction::sample`] draws `wo`.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> f32 {
        match self {
            PhaseFunction::Isotropic => isotropic::eval(),
            PhaseFunction::HenyeyGreenstein(hg) => hg.eval(wi.dot(wo)),
        }
    }

    #[inline]
    pub fn sample(&self, wi: Vec3, u: Vec2) -> Option<PhaseSample> {
        let s = match self {
            PhaseFunction::Isotropic => isotropic::sample(u),
            PhaseFunction::HenyeyGreenstein(hg) => hg.sample(wi, u),
        };
        (s.pdf > 0.0 && s.pdf.is_finite() && s.wo.is_finite()).then_some(s)
    }
}
