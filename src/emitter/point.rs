//! Mitsuba's `point` emitter: an isotropic point light of radiant intensity I (W/sr), seen
//! from a point at distance r with irradiance I / r² (a Dirac delta in position).

use super::{DirectionSample, EmitterRay};
use crate::geometry::Ray;
use crate::sampling::square_to_uniform_sphere;
use crate::texture::ColorValue;
use glam::{Vec2, Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct PointEmitter {
    pub position: Vec3,
    pub intensity: ColorValue,
}

impl PointEmitter {
    pub fn sample_direction(&self, p_ref: Vec3, wl: Vec4) -> Option<DirectionSample> {
        let v = self.position - p_ref;
        let dist2 = v.length_squared();
        if !(dist2 > 0.0 && dist2.is_finite()) {
            return None;
        }
        let dist = dist2.sqrt();
        Some(DirectionSample::from_point(
            self.position,
            v / dist,
            dist,
            self.intensity.eval(wl) / dist2,
        ))
    }

    /// A ray in a uniformly drawn direction, weight 4π I.
    pub fn sample_ray(&self, u: Vec2, wl: Vec4) -> EmitterRay {
        EmitterRay::from_point(
            Ray::new(self.position, square_to_uniform_sphere(u), f32::INFINITY),
            self.intensity.eval(wl) * (4.0 * std::f32::consts::PI),
        )
    }
}
