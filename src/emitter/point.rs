//! Mitsuba's `point` emitter: an isotropic point light of radiant intensity I (W/sr), seen
//! from a point at distance r with irradiance I / r² (a Dirac delta in position).

use super::DirectionSample;
use crate::bsdf::Spectrum;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct PointEmitter {
    pub position: Vec3,
    pub intensity: Spectrum,
}

impl PointEmitter {
    pub fn sample_direction(&self, p_ref: Vec3) -> Option<DirectionSample> {
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
            self.intensity / dist2,
        ))
    }
}
