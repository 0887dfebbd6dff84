//! `phong`: the energy-normalised modified Phong model (Lafortune and Willems 1994, "Using
//! the Modified Phong Reflectance Model for Physically Based Rendering"), with the
//! parameters of Mitsuba 0.6's `phong` plugin (Mitsuba 3 has none): `exponent` n (default
//! 30), `diffuse_reflectance` kd (default 0.5) and `specular_reflectance` ks (default 0.2).
//!
//!   f(wi, wo) = kd / π + ks (n + 2) / (2π) · max(0, cos α)ⁿ,
//!
//! α the angle between wo and the mirror direction of wi. The lobe's normalisation makes
//! ∫ (n + 2) / (2π) cosⁿ α cos θo dωo = cos θr ≤ 1 (θr the mirror direction's angle), so the
//! albedo stays ≤ kd + ks, and ≤ 1 when kd + ks ≤ 1 (a larger sum is refused for constant
//! values). Symmetric in wi and wo (cos α = wo · reflect(wi) = wi · reflect(wo)): reciprocal.
//!
//! Sampling picks the specular lobe with probability w = mean(ks) / (mean(ks) + mean(kd))
//! (Mitsuba 0.6's rule): cos α = u^(1/(n+1)) around the mirror direction, density
//! (n + 1) / (2π) cosⁿ α, a direction below the surface rejected; else cosine-weighted. The
//! pdf is the mixture of both. One-sided, like Mitsuba's: black from below.

use super::plugin::{BsdfModel, ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use crate::sampling::{square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf};
use crate::spectrum::{to_rgb, ColorRole};
use glam::{DVec3, Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// `phong`'s parameters (Mitsuba 0.6's names and defaults).
const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "exponent",
        kind: ParamKind::Float,
        default: 30.0,
        min: 0.0,
        max: 1e5,
        doc: "n, the specular lobe's exponent",
    },
    ParamSpec {
        name: "diffuse_reflectance",
        kind: ParamKind::Color(ColorRole::Reflectance),
        default: 0.5,
        min: 0.0,
        max: 1.0,
        doc: "kd, the diffuse albedo",
    },
    ParamSpec {
        name: "specular_reflectance",
        kind: ParamKind::Color(ColorRole::Reflectance),
        default: 0.2,
        min: 0.0,
        max: 1.0,
        doc: "ks, the specular lobe's albedo at normal incidence",
    },
];

#[derive(Clone, Debug)]
pub struct Phong {
    pub exponent: f32,
    pub diffuse_reflectance: Spectrum,
    pub specular_reflectance: Spectrum,
}

impl TablePlugin for Phong {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        Phong::new(
            v[0].x as f32,
            crate::spectrum::from_rgb_f64(v[1]),
            crate::spectrum::from_rgb_f64(v[2]),
        )
    }

    /// kd + ks ≤ 1 in every channel (to 1e-6) when both are constants: more would reflect
    /// more light than arrives.
    fn check(v: &[Option<DVec3>]) -> Result<(), String> {
        if let (Some(Some(d)), Some(Some(s))) = (v.get(1), v.get(2)) {
            if (0..3).any(|c| d[c] + s[c] > 1.0 + 1e-6) {
                return Err(format!(
                    "diffuse_reflectance + specular_reflectance exceeds 1 ({d:?} + {s:?}): the surface would reflect more light than it receives"
                ));
            }
        }
        Ok(())
    }
}

impl Phong {
    pub fn new(
        exponent: f32,
        diffuse_reflectance: Spectrum,
        specular_reflectance: Spectrum,
    ) -> Self {
        Phong {
            exponent,
            diffuse_reflectance,
            specular_reflectance,
        }
    }

    /// Probability of sampling the specular lobe.
    fn specular_weight(&self) -> f32 {
        let s = to_rgb(self.specular_reflectance).element_sum() / 3.0;
        let d = to_rgb(self.diffuse_reflectance).element_sum() / 3.0;
        if s + d > 0.0 {
            s / (s + d)
        } else {
            0.5
        }
    }

    /// cosⁿ α, α the angle between wo and the mirror direction of wi; 0 beyond 90° (also
    /// for n = 0, where the lobe is a uniform hemisphere about the mirror direction).
    fn lobe(&self, wi: Vec3, wo: Vec3) -> f32 {
        let cos_alpha = -wi.x * wo.x - wi.y * wo.y + wi.z * wo.z;
        if cos_alpha > 0.0 {
            cos_alpha.powf(self.exponent)
        } else {
            0.0
        }
    }
}

impl BsdfModel for Phong {
    const NAME: &'static str = "phong";

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let n = self.exponent;
        let lobe = (n + 2.0) / (2.0 * PI) * self.lobe(wi, wo);
        (self.diffuse_reflectance * FRAC_1_PI + self.specular_reflectance * lobe) * wo.z
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let n = self.exponent;
        let w = self.specular_weight();
        let specular = (n + 1.0) / (2.0 * PI) * self.lobe(wi, wo);
        w * specular + (1.0 - w) * square_to_cosine_hemisphere_pdf(wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let wo = if u1 < self.specular_weight() {
            let r = Vec3::new(-wi.x, -wi.y, wi.z);
            let cos_a = u2.y.powf(1.0 / (self.exponent + 1.0));
            let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
            let (sin_phi, cos_phi) = crate::math::sin_cosf(2.0 * PI * u2.x);
            let (t, b) = r.any_orthonormal_pair();
            let wo = (t * cos_phi + b * sin_phi) * sin_a + r * cos_a;
            if wo.z <= 0.0 {
                return None;
            }
            wo
        } else {
            square_to_cosine_hemisphere(u2)
        };
        BsdfSample::smooth(wo, self.pdf(wi, wo), || self.eval(wi, wo), 1.0)
    }

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            1 => self.diffuse_reflectance = v,
            2 => self.specular_reflectance = v,
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    /// ∫ f(wo) dω over the upper hemisphere for an f that depends on θo only, by the midpoint
    /// rule in θ (200,000 steps).
    fn integrate_over_theta(f: impl Fn(Vec3) -> f64) -> f64 {
        let steps = 200_000;
        let sum: f64 = (0..steps)
            .map(|k| {
                let theta = (k as f64 + 0.5) / steps as f64 * FRAC_PI_2;
                let wo = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
                f(wo) * theta.sin() * 2.0 * PI
            })
            .sum();
        sum * FRAC_PI_2 / steps as f64
    }

    /// The specular lobe is sampled with Mitsuba's probability s̄ / (d̄ + s̄), the means of the
    /// two reflectances (`phong.cpp`'s `m_specular_sampling_weight`): seen in the density of
    /// a direction outside the specular lobe, (1 − w) cos θo / π.
    #[test]
    fn lobes_are_picked_with_mitsubas_probability() {
        let kd = crate::spectrum::from_rgb(Vec3::new(0.2, 0.4, 0.6)); // mean 0.4
        let ks = crate::spectrum::from_rgb(Vec3::new(0.1, 0.1, 0.4)); // mean 0.2
        let b = Phong::new(20.0, kd, ks);
        let wi = Vec3::new(0.6, 0.0, 0.8);
        // the mirror direction is (−0.6, 0, 0.8); this wo is at more than 90° from it
        let wo = Vec3::new(0.8, 0.0, 0.6);
        assert_eq!(b.lobe(wi, wo), 0.0);
        let w = 1.0 - b.pdf(wi, wo) as f64 * std::f64::consts::PI / 0.6;
        assert!((w - 0.2 / 0.6).abs() < 1e-6, "specular weight {w}");
    }

    #[test]
    fn specular_lobe_of_normal_incidence_integrates_to_one() {
        // ∫ (n + 2) / (2π) cosⁿ α cos θo dω = 1 when the mirror direction is the normal:
        // the lobe alone (kd = 0, ks = 1) has albedo 1 at normal incidence, by quadrature in θ.
        for n in [1.0f32, 10.0, 200.0] {
            let b = Phong::new(n, Spectrum::ZERO, Spectrum::ONE);
            let albedo = integrate_over_theta(|wo| b.eval(Vec3::Z, wo).x as f64);
            assert!((albedo - 1.0).abs() < 1e-4, "n = {n}: {albedo}");
        }
    }

    #[test]
    fn pdf_of_normal_incidence_integrates_to_one() {
        // At normal incidence the specular lobe (n + 1)/(2π) cosⁿ α lies wholly above the
        // horizon, so the mixture with the cosine lobe is a density: ∫ pdf dω = 1, by the same
        // quadrature in θ (the pdf does not depend on φ here).
        for (n, kd, ks) in [(1.0f32, 0.5, 0.5), (10.0, 0.2, 0.8), (200.0, 0.0, 1.0)] {
            let b = Phong::new(n, Spectrum::splat(kd), Spectrum::splat(ks));
            let total = integrate_over_theta(|wo| b.pdf(Vec3::Z, wo) as f64);
            assert!((total - 1.0).abs() < 1e-4, "n = {n}: {total}");
        }
    }
}
