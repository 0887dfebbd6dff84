//! Mitsuba's `isotropic` phase function: light scatters equally in every direction,
//! p = 1 / (4π), sampled exactly (uniform directions on the sphere).
//!
//! ```xml
//! <phase type="isotropic"/>
//! ```

use super::PhaseSample;
use crate::sampling::square_to_uniform_sphere;
use glam::Vec2;

const INV_FOUR_PI: f32 = 0.25 * std::f32::consts::FRAC_1_PI;

#[inline]
pub fn eval() -> f32 {
    INV_FOUR_PI
}

#[inline]
pub fn sample(u: Vec2) -> PhaseSample {
    PhaseSample {
        wo: square_to_uniform_sphere(u),
        weight: 1.0,
        pdf: INV_FOUR_PI,
    }
}
