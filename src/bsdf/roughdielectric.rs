//! Mitsuba's `roughdielectric`: the microfacet BSDF of a rough interface between two
//! dielectrics, Walter, Marschner, Li and Torrance 2007, "Microfacet Models for Refraction
//! through Rough Surfaces": reflection (eq. 20) with F(wi·m) and transmission (eq. 21) with
//! 1 − F(wi·m) through the generalised half vector m ∝ wi + η_o/η_i · wo (eq. 16), with the
//! Jacobians of eqs. 14 and 17. Two-sided: from inside, the relative IOR is 1/η.
//!
//! Conventions as Mitsuba's: eval includes |cos θo|; transmitted radiance is scaled by
//! (η_i / η_o)² (radiance mode; see [`super::dielectric`]); the sampler draws m (visible
//! normals of the side wi lies on, or D(m) cos θm with Walter's roughness widening
//! 1.2 − 0.2 √|cos θi| of §5.3 when `sample_visible` is off) and picks reflection with
//! probability F(wi·m).

use super::conductor::SPECULAR_REFLECTANCE;
use super::dielectric::{IORS, SPECULAR_TRANSMITTANCE};
use super::fresnel::{fresnel_dielectric, reflect, refract};
use super::microfacet::Microfacet;
use super::microfacet::{ALPHA_UV, DISTRIBUTION, SAMPLE_VISIBLE};
use super::plugin::{ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use glam::DVec3;
use glam::{Vec2, Vec3};

/// `roughdielectric`'s parameters (Mitsuba 3.9.1's names and defaults).
const PARAMS: &[ParamSpec] = &[
    DISTRIBUTION,
    ALPHA_UV[0],
    ALPHA_UV[1],
    SAMPLE_VISIBLE,
    IORS[0],
    IORS[1],
    SPECULAR_REFLECTANCE,
    SPECULAR_TRANSMITTANCE,
];

#[derive(Clone, Debug)]
pub struct RoughDielectric {
    pub distribution: Microfacet,
    /// int_ior / ext_ior.
    pub eta: f32,
    pub specular_reflectance: Spectrum,
    pub specular_transmittance: Spectrum,
}

/// The microfacet normal of a direction pair, flipped to the upper hemisphere, and the
/// relative IOR η_o / η_i (1 for reflection).
pub(super) fn half_vector(wi: Vec3, wo: Vec3, eta: f32) -> Option<(Vec3, f32, bool)> {
    let (ci, co) = (wi.z, wo.z);
    if ci == 0.0 || co == 0.0 {
        return None;
    }
    // By the signs, not the product's (Mitsuba's `cos θi cos θo > 0`): the product of two
    // grazing cosines underflows to ±0 and would make a reflection a refraction.
    let reflect = (ci > 0.0) == (co > 0.0);
    let eta_rel = if reflect {
        1.0
    } else if ci > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let m = (wi + wo * eta_rel).try_normalize()?;
    let m = if m.z < 0.0 { -m } else { m };
    Some((m, eta_rel, reflect))
}

impl RoughDielectric {
    /// The distribution the sampler uses (widened without visible-normal sampling).
    fn sampling_distribution(&self, wi: Vec3) -> Microfacet {
        if self.distribution.sample_visible {
            self.distribution
        } else {
            self.distribution.scaled(1.2 - 0.2 * wi.z.abs().sqrt())
        }
    }

    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        let Some((m, eta_rel, is_reflection)) = half_vector(wi, wo, self.eta) else {
            return Spectrum::ZERO;
        };
        let d = self.distribution.d(m);
        if d == 0.0 {
            return Spectrum::ZERO;
        }
        let g = self.distribution.g_eval(wi, wo, m);
        if g == 0.0 {
            return Spectrum::ZERO;
        }
        let (wim, wom) = (wi.dot(m) as f64, wo.dot(m) as f64);
        let f = fresnel_dielectric(wi.dot(m), self.eta).f as f64;
        let ci = (wi.z as f64).abs();
        let (d, g) = (d as f64, g as f64);
        if is_reflection {
            self.specular_reflectance * (f * d * g / (4.0 * ci)) as f32
        } else {
            let e = eta_rel as f64;
            let denom = wim + e * wom;
            // Walter et al. eq. 21 with η_o² replaced by η_i² (radiance mode: the importance
            // form scaled by (η_i/η_o)²): (1 − F) D G |wi·m| |wo·m| / (|cos θi| (wi·m + η wo·m)²)
            // with η = η_o/η_i. With D G → δ this gives the smooth weight (η_i/η_o)² (1 − F).
            let v = (1.0 - f) * d * g * (wim * wom).abs() / (ci * denom * denom);
            self.specular_transmittance * v as f32
        }
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some((m, eta_rel, is_reflection)) = half_vector(wi, wo, self.eta) else {
            return 0.0;
        };
        let (wim, wom) = (wi.dot(m), wo.dot(m));
        // The microfacet must face both directions consistently with their sides.
        if wim * wi.z <= 0.0 || wom * wo.z <= 0.0 {
            return 0.0;
        }
        let sign = wi.z.signum();
        let pdf_m = self.sampling_distribution(wi).pdf(wi * sign, m) as f64;
        let f = fresnel_dielectric(wim, self.eta).f as f64;
        let p = if is_reflection {
            f * pdf_m / (4.0 * (wom as f64).abs())
        } else {
            let e = eta_rel as f64;
            let denom = wim as f64 + e * wom as f64;
            (1.0 - f) * pdf_m * e * e * (wom as f64).abs() / (denom * denom)
        };
        if p.is_finite() {
            p as f32
        } else {
            0.0
        }
    }

    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z == 0.0 || !wi.is_finite() {
            return None;
        }
        let sign = wi.z.signum();
        let (m, _) = self.sampling_distribution(wi).sample(wi * sign, u2)?;
        // Without visible-normal sampling, m may face away from wi: no light arrives there.
        if wi.dot(m) * sign <= 0.0 {
            return None;
        }
        let fr = fresnel_dielectric(wi.dot(m), self.eta);
        let (wo, eta) = if u1 < fr.f {
            let wo = reflect(wi, m);
            if wo.z * wi.z <= 0.0 {
                return None;
            }
            (wo, 1.0)
        } else {
            let wo = refract(wi, m, fr.cos_theta_t, fr.eta_ti);
            if wo.z * wi.z >= 0.0 {
                return None;
            }
            (wo, fr.eta_it)
        };
        let pdf = self.pdf(wi, wo);
        BsdfSample::smooth(wo, pdf, || self.eval(wi, wo), eta)
    }
}

impl TablePlugin for RoughDielectric {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        RoughDielectric {
            distribution: Microfacet::from_params(v[0].x, v[1].x, v[2].x, v[3].x),
            eta: (v[4].x / v[5].x) as f32,
            specular_reflectance: crate::spectrum::from_rgb_f64(v[6]),
            specular_transmittance: crate::spectrum::from_rgb_f64(v[7]),
        }
    }
}

impl super::BsdfModel for RoughDielectric {
    const NAME: &'static str = "roughdielectric";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            1 => self.distribution.set_alpha_u(v.x),
            2 => self.distribution.set_alpha_v(v.x),
            6 => self.specular_reflectance = v,
            7 => self.specular_transmittance = v,
            _ => {}
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        RoughDielectric::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        RoughDielectric::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        RoughDielectric::sample(self, wi, u1, u2)
    }

    #[inline]
    fn has_smooth_lobe(&self, _wi: Vec3) -> bool {
        true
    }

    fn is_transmissive(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reflection or refraction is decided by the sides of wi and wo, also for grazing
    /// directions whose cosines' product underflows (1e-25 · 1e-25 is 0 in f32).
    #[test]
    fn half_vector_tells_reflection_by_the_sides() {
        let g = 1e-25f32;
        let graze = |z: f32| Vec3::new((1.0 - z * z).sqrt(), 0.0, z);
        let up = Vec3::new(0.6, 0.0, 0.8);
        for (wi, wo, reflect) in [
            (graze(g), graze(g), true),
            (graze(-g), graze(-g), true),
            (graze(g), graze(-g), false),
            (up, graze(g), true),
            (up, Vec3::new(0.0, 0.6, -0.8), false),
        ] {
            let (_, eta, r) = half_vector(wi, wo, 1.5).unwrap();
            assert_eq!(r, reflect, "wi {wi} wo {wo}");
            assert_eq!(eta == 1.0, reflect);
        }
    }
}
