//! Mitsuba's `constant` emitter: the same radiance L arriving from every direction at
//! infinity, sampled uniformly over the sphere of directions (pdf 1 / 4π).

use super::DirectionSample;
use crate::sampling::square_to_uniform_sphere;
use crate::texture::ColorValue;
use glam::{Vec2, Vec3, Vec4};

/// 1 / 4π.
pub const UNIFORM_SPHERE_PDF: f32 = 0.25 * std::f32::consts::FRAC_1_PI;

#[derive(Clone, Debug)]
pub struct ConstantEmitter {
    pub radiance: ColorValue,
}

impl ConstantEmitter {
    pub fn sample_direction(&self, u: Vec2, wl: Vec4) -> Option<DirectionSample> {
        let d = square_to_uniform_sphere(u);
        Some(DirectionSample {
            p: Vec3::ZERO,
            p_error: Vec3::ZERO,
            n: Vec3::ZERO,
            d,
            dist: f32::INFINITY,
            pdf: UNIFORM_SPHERE_PDF,
            radiance: self.radiance.eval(wl),
            delta: false,
        })
    }
}
