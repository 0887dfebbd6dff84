//! Mitsuba's `hg`: the Henyey–Greenstein phase function (Henyey and Greenstein 1941,
//! "Diffuse radiation in the galaxy"), the one-parameter model of forward (`g` > 0) or
//! backward (`g` < 0) scattering whose mean cosine is `g`:
//!
//! p(θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}),
//!
//! θ the angle between the incoming ray's direction and `wo` (with Mitsuba's `wi = −ray.d`,
//! cos θ = −wi·wo). Sampled exactly by inverting its CDF in cos θ (pbrt-v4 §11.3.1).
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `g` | float in (−1, 1) | 0.8 |
//!
//! ```xml
//! <phase type="hg"> <float name="g" value="0.4"/> </phase>
//! ```

use super::PhaseSample;
use crate::geometry::Frame;
use glam::{Vec2, Vec3};

const INV_FOUR_PI: f32 = 0.25 * std::f32::consts::FRAC_1_PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HenyeyGreenstein {
    pub g: f32,
}

impl HenyeyGreenstein {
    /// p as a function of `cos_wi_wo` = wi·wo (= −cos θ).
    #[inline]
    pub fn eval(&self, cos_wi_wo: f32) -> f32 {
        let g = self.g;
        let denom = 1.0 + g * g + 2.0 * g * cos_wi_wo;
        INV_FOUR_PI * (1.0 - g * g) / (denom * denom.max(0.0).sqrt())
    }

    #[inline]
    pub fn sample(&self, wi: Vec3, u: Vec2) -> PhaseSample {
        // cos θ about the forward direction −wi, in f64: for small |g| the inversion cancels.
        let g = self.g as f64;
        let ux = u.x as f64;
        let cos_theta = if g.abs() < 1e-6 {
            1.0 - 2.0 * ux
        } else {
            let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * ux);
            ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
        } as f32;
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let (sin_phi, cos_phi) = crate::math::sin_cosf(2.0 * std::f32::consts::PI * u.y);
        let forward = Frame::from_normal(-wi);
        let wo = forward.to_world(Vec3::new(
            sin_theta * cos_phi,
            sin_theta * sin_phi,
            cos_theta,
        ));
        let pdf = self.eval(wi.dot(wo));
        PhaseSample {
            wo,
            weight: 1.0,
            pdf,
        }
    }
}
