//! Mitsuba's `directional` emitter: light arriving from infinity along one direction with
//! irradiance E (W/m²) on a surface perpendicular to it (a Dirac delta in direction).

use super::DirectionSample;
use crate::texture::ColorValue;
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct DirectionalEmitter {
    /// Unit direction in which the light travels.
    pub direction: Vec3,
    pub irradiance: ColorValue,
}

impl DirectionalEmitter {
    pub fn sample_direction(&self, wl: Vec4) -> DirectionSample {
        DirectionSample {
            p: Vec3::ZERO,
            p_error: Vec3::ZERO,
            n: Vec3::ZERO,
            d: -self.direction,
            dist: f32::INFINITY,
            pdf: 1.0,
            radiance: self.irradiance.eval(wl),
            delta: true,
        }
    }
}
