//! Mitsuba's `thindielectric`: a thin slab of dielectric (e.g. a window pane) with two
//! parallel smooth interfaces and no absorption inside. Light is reflected with the total
//! reflectance of the infinite series of internal reflections, R' = R + T² R / (1 − R²)
//! (T = 1 − R, R the single-interface Fresnel reflectance), and otherwise passes straight
//! through undeflected (wo = −wi); both lobes are Dirac deltas. Two-sided; the medium on
//! both sides is the same, so no radiance scaling (η = 1 along the path).

use super::fresnel::fresnel_dielectric;
use super::plugin::{ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use arrayvec::ArrayVec;
use glam::DVec3;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct ThinDielectric {
    /// int_ior / ext_ior.
    pub eta: f32,
    pub specular_reflectance: Spectrum,
    pub specular_transmittance: Spectrum,
}

impl ThinDielectric {
    /// Total reflectance R' of the slab at incidence cosine |cos θ|.
    pub fn reflectance(&self, cos_theta: f32) -> f32 {
        let r = fresnel_dielectric(cos_theta.abs(), self.eta).f;
        if r < 1.0 {
            let t = 1.0 - r;
            r + t * t * r / (1.0 - r * r)
        } else {
            1.0
        }
    }

    /// The straight-through transmission (1 − R') · `specular_transmittance`, Mitsuba's
    /// `eval_null_transmission`.
    pub fn null_transmission(&self, wi: Vec3) -> Spectrum {
        self.specular_transmittance * (1.0 - self.reflectance(wi.z))
    }

    pub fn eval(&self, _wi: Vec3, _wo: Vec3) -> Spectrum {
        Spectrum::ZERO
    }

    pub fn pdf(&self, _wi: Vec3, _wo: Vec3) -> f32 {
        0.0
    }

    pub fn sample(&self, wi: Vec3, u1: f32) -> Option<BsdfSample> {
        if wi.z == 0.0 || !wi.is_finite() {
            return None;
        }
        let r = self.reflectance(wi.z);
        Some(if u1 < r {
            self.reflection(wi, r)
        } else {
            self.transmission(wi, r)
        })
    }

    /// Both lobes at once, each with its probability as `pdf` (those of nonzero
    /// probability), as [`super::dielectric::Dielectric::branches`].
    pub fn branches(&self, wi: Vec3) -> ArrayVec<BsdfSample, 2> {
        let mut out = ArrayVec::new();
        if wi.z == 0.0 || !wi.is_finite() {
            return out;
        }
        let r = self.reflectance(wi.z);
        if r > 0.0 {
            out.push(self.reflection(wi, r));
        }
        if r < 1.0 {
            out.push(self.transmission(wi, r));
        }
        out
    }

    fn reflection(&self, wi: Vec3, r: f32) -> BsdfSample {
        BsdfSample {
            wo: Vec3::new(-wi.x, -wi.y, wi.z),
            pdf: r,
            weight: self.specular_reflectance,
            eta: 1.0,
            delta: true,
            null: false,
        }
    }

    fn transmission(&self, wi: Vec3, r: f32) -> BsdfSample {
        BsdfSample {
            wo: -wi,
            pdf: 1.0 - r,
            weight: self.specular_transmittance,
            eta: 1.0,
            delta: true,
            null: true,
        }
    }
}

impl TablePlugin for ThinDielectric {
    /// `dielectric`'s parameters.
    const PARAMS: &'static [ParamSpec] = super::dielectric::PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        ThinDielectric {
            eta: (v[0].x / v[1].x) as f32,
            specular_reflectance: crate::spectrum::from_rgb_f64(v[2]),
            specular_transmittance: crate::spectrum::from_rgb_f64(v[3]),
        }
    }
}

impl super::BsdfModel for ThinDielectric {
    const NAME: &'static str = "thindielectric";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            2 => self.specular_reflectance = v,
            3 => self.specular_transmittance = v,
            _ => {}
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        ThinDielectric::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        ThinDielectric::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, _u2: Vec2) -> Option<BsdfSample> {
        ThinDielectric::sample(self, wi, u1)
    }

    #[inline]
    fn has_smooth_lobe(&self, _wi: Vec3) -> bool {
        false
    }

    fn is_transmissive(&self) -> bool {
        true
    }
}
