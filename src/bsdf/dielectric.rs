//! Mitsuba's `dielectric`: a smooth interface between two dielectrics (relative IOR
//! η = int_ior / ext_ior), two Dirac-delta lobes: mirror reflection with the Fresnel
//! reflectance F and refraction (Snell's law) with 1 − F, picked with probabilities F and
//! 1 − F so that the weights are `specular_reflectance` and `specular_transmittance`.
//! Two-sided: from inside (cos θi < 0) the relative IOR is 1/η, with total internal
//! reflection.
//!
//! Radiance is not conserved across refraction but radiance / η² is (Veach 1997 §5.2): the
//! transmitted weight carries (η_i / η_t)², as Mitsuba applies in its radiance mode, and the
//! sample reports η_t / η_i so that the path integrator's Russian roulette can undo it.

use super::conductor::SPECULAR_REFLECTANCE;
use super::fresnel::{fresnel_dielectric, refract, DielectricFresnel};
use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use crate::spectrum::ColorRole;
use arrayvec::ArrayVec;
use glam::DVec3;
use glam::{Vec2, Vec3};

/// `int_ior` and `ext_ior`, the dielectrics' IORs inside and outside (numbers or names).
pub const IORS: [ParamSpec; 2] = [
    ParamSpec::new("int_ior", ParamKind::Ior("bk7"), 1.5046, "the IOR inside"),
    ParamSpec::new(
        "ext_ior",
        ParamKind::Ior("air"),
        1.000277,
        "the IOR outside",
    ),
];

/// `specular_transmittance`: a factor on the refracted light (Mitsuba's default 1).
pub const SPECULAR_TRANSMITTANCE: ParamSpec = ParamSpec::new(
    "specular_transmittance",
    ParamKind::Color(ColorRole::Reflectance),
    1.0,
    "a factor on the refracted light",
);

/// The parameters of `dielectric` and `thindielectric` (Mitsuba 3.9.1's names and defaults).
pub const PARAMS: &[ParamSpec] = &[
    IORS[0],
    IORS[1],
    SPECULAR_REFLECTANCE,
    SPECULAR_TRANSMITTANCE,
];

#[derive(Clone, Debug)]
pub struct Dielectric {
    /// int_ior / ext_ior.
    pub eta: f32,
    pub specular_reflectance: Spectrum,
    pub specular_transmittance: Spectrum,
}

impl Dielectric {
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
        let fr = fresnel_dielectric(wi.z, self.eta);
        Some(if u1 < fr.f {
            self.reflection(wi, fr)
        } else {
            self.transmission(wi, fr)
        })
    }

    /// Both lobes at once, each with its probability as `pdf` (those of nonzero
    /// probability): `sample`'s outcomes, so that Σ pdf · weight · g(wo) over the branches is
    /// the expectation of `weight · g(wo)` over `sample` for any g. For splitting a path here.
    pub fn branches(&self, wi: Vec3) -> ArrayVec<BsdfSample, 2> {
        let mut out = ArrayVec::new();
        if wi.z == 0.0 || !wi.is_finite() {
            return out;
        }
        let fr = fresnel_dielectric(wi.z, self.eta);
        if fr.f > 0.0 {
            out.push(self.reflection(wi, fr));
        }
        if fr.f < 1.0 {
            out.push(self.transmission(wi, fr));
        }
        out
    }

    fn reflection(&self, wi: Vec3, fr: DielectricFresnel) -> BsdfSample {
        BsdfSample {
            wo: Vec3::new(-wi.x, -wi.y, wi.z),
            pdf: fr.f,
            weight: self.specular_reflectance,
            eta: 1.0,
            delta: true,
            null: false,
        }
    }

    fn transmission(&self, wi: Vec3, fr: DielectricFresnel) -> BsdfSample {
        BsdfSample {
            wo: refract(wi, Vec3::Z, fr.cos_theta_t, fr.eta_ti),
            pdf: 1.0 - fr.f,
            weight: self.specular_transmittance * (fr.eta_ti * fr.eta_ti),
            eta: fr.eta_it,
            delta: true,
            null: false,
        }
    }
}

impl TablePlugin for Dielectric {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        Dielectric {
            eta: (v[0].x / v[1].x) as f32,
            specular_reflectance: crate::spectrum::from_rgb_f64(v[2]),
            specular_transmittance: crate::spectrum::from_rgb_f64(v[3]),
        }
    }
}

impl super::BsdfModel for Dielectric {
    const NAME: &'static str = "dielectric";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            2 => self.specular_reflectance = v,
            3 => self.specular_transmittance = v,
            _ => {}
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        Dielectric::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        Dielectric::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, _u2: Vec2) -> Option<BsdfSample> {
        Dielectric::sample(self, wi, u1)
    }

    #[inline]
    fn has_smooth_lobe(&self, _wi: Vec3) -> bool {
        false
    }

    fn is_transmissive(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::super::thindielectric::ThinDielectric;
    use super::*;

    /// `sample(wi, u)` of one BSDF at a fixed wi.
    type SampleFn<'a> = &'a dyn Fn(f32) -> Option<BsdfSample>;

    /// `branches` lists exactly `sample`'s outcomes with their probabilities: from both
    /// sides, at grazing angles and under total internal reflection (one branch), for the
    /// dielectric and the thin dielectric.
    #[test]
    fn branches_are_the_outcomes_of_sample() {
        let dielectric = Dielectric {
            eta: 1.5,
            specular_reflectance: crate::spectrum::rgb(0.9, 0.8, 0.7),
            specular_transmittance: crate::spectrum::rgb(0.6, 0.5, 0.4),
        };
        let thin = ThinDielectric {
            eta: 1.33,
            specular_reflectance: crate::spectrum::rgb(0.9, 0.8, 0.7),
            specular_transmittance: crate::spectrum::rgb(0.6, 0.5, 0.4),
        };
        let mut tir = 0;
        for k in 0..400 {
            let cos = -1.0 + (k as f32 + 0.5) / 200.0;
            let phi = k as f32 * 0.7;
            let sin = (1.0 - cos * cos).sqrt();
            let wi = Vec3::new(sin * phi.cos(), sin * phi.sin(), cos);
            let cases: [(ArrayVec<BsdfSample, 2>, SampleFn); 2] = [
                (dielectric.branches(wi), &|u| dielectric.sample(wi, u)),
                (thin.branches(wi), &|u| thin.sample(wi, u)),
            ];
            for (branches, sample) in cases {
                assert!(branches.iter().all(|b| b.pdf > 0.0), "{branches:?}");
                let total: f32 = branches.iter().map(|b| b.pdf).sum();
                assert!(
                    (total - 1.0).abs() < 1e-6,
                    "wi {wi}: probabilities sum to {total}"
                );
                tir += (branches.len() == 1) as u32;
                // u below the first branch's probability picks it, above picks the second
                let mut seen = [0.0f32; 2];
                for j in 0..1000 {
                    let u = (j as f32 + 0.5) / 1000.0;
                    let s = sample(u).expect("a sample");
                    let b = branches
                        .iter()
                        .position(|b| b.wo == s.wo && b.weight == s.weight && b.pdf == s.pdf)
                        .unwrap_or_else(|| panic!("wi {wi}, u {u}: {s:?} not a branch"));
                    seen[b] += 1e-3;
                }
                for (b, share) in branches.iter().zip(seen) {
                    assert!(
                        (b.pdf - share).abs() < 2e-3,
                        "wi {wi}: {b:?} sampled {share}"
                    );
                }
            }
        }
        assert!(
            tir > 0,
            "no angle under total internal reflection was tested"
        );
        // Index-matched (F = 0): transmission alone, never a reflection of probability 0.
        let matched = Dielectric {
            eta: 1.0,
            ..dielectric.clone()
        };
        let wi = Vec3::new(0.6, 0.0, 0.8);
        assert_eq!(matched.branches(wi).len(), 1, "{:?}", matched.branches(wi));
        // Where `sample` has no outcome (grazing, not finite), neither has `branches`.
        for wi in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(f32::NAN, 0.0, 1.0)] {
            assert!(dielectric.sample(wi, 0.5).is_none() && dielectric.branches(wi).is_empty());
            assert!(thin.sample(wi, 0.5).is_none() && thin.branches(wi).is_empty());
        }
    }
}
