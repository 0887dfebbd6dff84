//! Mitsuba's `conductor`: a perfectly smooth metal, a Dirac-delta mirror reflection weighted
//! by the exact conductor Fresnel reflectance of the complex IOR η + ik (see
//! [`super::fresnel::fresnel_conductor`]) and by `specular_reflectance`. One-sided (front side
//! of the shading frame). With Mitsuba's default `material` "none" (η = 0, k = 1) it is an
//! ideal mirror whose reflectance is exactly `specular_reflectance`.

use super::fresnel::fresnel_conductor;
use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use crate::spectrum::ColorRole;
use glam::DVec3;
use glam::{Vec2, Vec3};

/// `eta` and `k`, or the named `material` (Mitsuba's conductors' complex IOR).
pub const ETA_K: [ParamSpec; 2] = [
    ParamSpec::new(
        "eta",
        ParamKind::ConductorEta,
        0.0,
        "η, the real part of the IOR per channel; or `material`, a named preset (default none: η = 0, k = 1)",
    )
    .range(0.0, f64::INFINITY),
    ParamSpec::new(
        "k",
        ParamKind::ConductorK,
        1.0,
        "k, the imaginary part (absorption)",
    )
    .range(0.0, f64::INFINITY),
];

/// `specular_reflectance`: a factor on the reflection (Mitsuba's default 1).
pub const SPECULAR_REFLECTANCE: ParamSpec = ParamSpec::new(
    "specular_reflectance",
    ParamKind::Color(ColorRole::Reflectance),
    1.0,
    "a factor on the reflected light",
);

/// `conductor`'s parameters (Mitsuba 3.9.1's names and defaults).
const PARAMS: &[ParamSpec] = &[ETA_K[0], ETA_K[1], SPECULAR_REFLECTANCE];

#[derive(Clone, Debug)]
pub struct Conductor {
    /// Real part of the relative IOR, per channel.
    pub eta: Spectrum,
    /// Imaginary part (absorption), per channel.
    pub k: Spectrum,
    pub specular_reflectance: Spectrum,
}

impl Conductor {
    /// A delta lobe only: the density of any given direction is zero.
    pub fn eval(&self, _wi: Vec3, _wo: Vec3) -> Spectrum {
        Spectrum::ZERO
    }

    pub fn pdf(&self, _wi: Vec3, _wo: Vec3) -> f32 {
        0.0
    }

    pub fn sample(&self, wi: Vec3, _u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let f = fresnel_conductor(wi.z, self.eta, self.k);
        Some(BsdfSample {
            wo: Vec3::new(-wi.x, -wi.y, wi.z),
            pdf: 1.0,
            weight: f * self.specular_reflectance,
            eta: 1.0,
            delta: true,
            null: false,
        })
    }
}

impl TablePlugin for Conductor {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        Conductor {
            eta: crate::spectrum::from_rgb_f64(v[0]),
            k: crate::spectrum::from_rgb_f64(v[1]),
            specular_reflectance: crate::spectrum::from_rgb_f64(v[2]),
        }
    }
}

impl super::BsdfModel for Conductor {
    const NAME: &'static str = "conductor";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            0 => self.eta = v,
            1 => self.k = v,
            2 => self.specular_reflectance = v,
            _ => {}
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        Conductor::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        Conductor::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, _u1: f32, u2: Vec2) -> Option<BsdfSample> {
        Conductor::sample(self, wi, u2)
    }

    #[inline]
    fn has_smooth_lobe(&self, _wi: Vec3) -> bool {
        false
    }
}
