//! Mitsuba's `roughplastic`: a diffuse base under a rough dielectric coating (Weidlich and
//! Wilkie 2007, "Arbitrarily Layered Micro-Facet Surfaces", as documented for Mitsuba):
//!
//! - specular: the rough dielectric reflection of the coating, the microfacet BRDF of Walter
//!   et al. 2007 (eq. 20) with the dielectric Fresnel term, times specular_reflectance;
//! - diffuse: f cos θo = T(cos θi) T(cos θo) / η² · R' cos θo / π, where T(μ) is the
//!   fraction of light that the rough coating transmits at incidence cosine μ (one minus the
//!   directional albedo of its reflection lobe), and R' = R / (1 − Fdr_int) or, with
//!   `nonlinear`, R / (1 − R Fdr_int), with Fdr_int the cosine-weighted internal reflectance
//!   of the coating, 1 − 2 ∫ T(μ) μ dμ / η² (light leaving a Lambertian base is refracted out
//!   with the external transmittance scaled by 1/η², by reciprocity).
//!
//! Mitsuba precomputes T in tables, and so does penumbra, by Mitsuba's method: the albedo at
//! 64 equispaced cosines (the first at 10⁻⁶), each integrated over the visible normals of the
//! coating by a tensor Gauss–Legendre rule on the unit square (32² nodes, 128² when η < 1),
//! linearly interpolated, and the internal reflectance as the mean over the same cosines.
//! Sampling picks the specular lobe with probability ∝ (1 − T(cos θi)) w_s against
//! T(cos θi)(1 − w_s) (w_s as in `plastic`); both lobes are smooth, so eval and pdf cover
//! everything. One-sided.

use super::conductor::SPECULAR_REFLECTANCE;
use super::fresnel::{fresnel_dielectric, reflect, refract};
use super::microfacet::Microfacet;
use super::microfacet::{DISTRIBUTION, SAMPLE_VISIBLE};
use super::plastic::{
    diffuse_with_internal_scattering, specular_lobe_probability, specular_sampling_weight,
};
use super::plastic::{DIFFUSE_REFLECTANCE, IORS, NONLINEAR};
use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use crate::math::gauss_legendre;
use crate::sampling::{square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf};
use glam::DVec3;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::FRAC_1_PI;

/// `roughplastic`'s parameters (Mitsuba 3.9.1's names and defaults); its roughness is one
/// number, from which the coating's tables are computed.
const PARAMS: &[ParamSpec] = &[
    DISTRIBUTION,
    ParamSpec::new(
        "alpha",
        ParamKind::Roughness {
            anisotropic: false,
            texture: false,
        },
        0.1,
        "the coating's roughness (a number)",
    )
    .range(0.0, f64::INFINITY),
    SAMPLE_VISIBLE,
    IORS[0],
    IORS[1],
    DIFFUSE_REFLECTANCE,
    SPECULAR_REFLECTANCE,
    NONLINEAR,
];

/// Cosines at which the coating's transmittance is tabulated.
const TABLE_SIZE: usize = 64;

#[derive(Clone, Debug)]
pub struct RoughPlastic {
    pub distribution: Microfacet,
    pub eta: f32,
    pub diffuse_reflectance: Spectrum,
    pub specular_reflectance: Spectrum,
    pub nonlinear: bool,
    /// External transmittance T(μ) at μ = i / (TABLE_SIZE − 1) (inline, so that the BSDF
    /// is copied without allocating when textures vary its colours per shading point).
    transmittance: [f32; TABLE_SIZE],
    /// Cosine-weighted internal reflectance of the coating.
    pub fdr_int: f32,
    pub specular_sampling_weight: f32,
}

/// Directional albedos of a rough dielectric interface of relative IOR `eta` (the side of
/// incidence has index 1) at the cosines μ = i / (TABLE_SIZE − 1), single scattering, by
/// Gauss–Legendre quadrature over the unit square that samples the visible normals m
/// (Heitz 2014 eq. 38), as Mitsuba computes its tables (32 nodes per axis for η > 1, 128
/// for η < 1, where total internal reflection makes the integrand less smooth):
/// - `Lobe::Reflection`: E[F(wi·m) G1(wo, m)], wo the mirror direction;
/// - `Lobe::Transmission`: E[(1 − F(wi·m)) G1(wt, m)], wt the refracted direction
///   (importance form: what crosses the interface, before the 1/η² radiance scaling).
///
/// Light that a microfacet sends into another one is lost (no multiple scattering), so the
/// two do not add up to 1 on rough interfaces. These are the tables Mitsuba's roughplastic
/// values correspond to (checked against its eval for several roughnesses).
fn albedo_table(distribution: &Microfacet, eta: f32, lobe: Lobe) -> Vec<f32> {
    let visible = Microfacet {
        sample_visible: true,
        ..*distribution
    };
    let (nodes, weights) = gauss_legendre(if eta > 1.0 { 32 } else { 128 });
    // Rows are independent (each its own μ): computed in parallel, the same values.
    (0..TABLE_SIZE)
        .into_par_iter()
        .map(|i| {
            let mu = (i as f32 / (TABLE_SIZE - 1) as f32).max(1e-6);
            let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
            let mut acc = 0.0f64;
            for (xa, wa) in nodes.iter().zip(&weights) {
                for (xc, wc) in nodes.iter().zip(&weights) {
                    // [−1, 1]² onto the unit square: the weights carry the Jacobian 1/4.
                    let w = wa * wc * 0.25;
                    let u = Vec2::new((0.5 * xa + 0.5) as f32, (0.5 * xc + 0.5) as f32);
                    let Some((m, _)) = visible.sample(wi, u) else {
                        continue;
                    };
                    let fr = fresnel_dielectric(wi.dot(m), eta);
                    acc += match lobe {
                        Lobe::Reflection => {
                            let wo = reflect(wi, m);
                            if wo.z > 0.0 {
                                w * fr.f as f64 * distribution.g1_eval(wo, m) as f64
                            } else {
                                0.0
                            }
                        }
                        Lobe::Transmission => {
                            let wt = refract(wi, m, fr.cos_theta_t, fr.eta_ti);
                            if fr.f < 1.0 && wt.z < 0.0 {
                                w * (1.0 - fr.f as f64) * distribution.g1_eval(wt, m) as f64
                            } else {
                                0.0
                            }
                        }
                    };
                }
            }
            acc.clamp(0.0, 1.0) as f32
        })
        .collect()
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobe {
    Reflection,
    Transmission,
}

/// The cosine-weighted hemispherical average 2 ∫₀¹ R(μ) μ dμ of a table, estimated as Mitsuba
/// does (determined by comparing its values for several roughnesses): the plain mean of
/// 2 R(μᵢ) μᵢ over the table's equispaced nodes μᵢ = i / (N − 1), which is the integral
/// times (N − 1)/N plus R(1)/N; with N = 64, about 1.5% below the exact integral.
pub fn table_average(table: &[f32]) -> f64 {
    let n = table.len();
    let sum: f64 = table
        .iter()
        .enumerate()
        .map(|(i, r)| 2.0 * *r as f64 * i as f64 / (n - 1) as f64)
        .sum();
    sum / n as f64
}

/// What roughplastic precomputes from its coating (distribution and η): the external
/// transmittance table and the internal reflectance. About 0.1 s to compute (a million
/// visible normals for the internal reflectance): the scene builder computes it once per
/// distinct coating.
#[derive(Clone, Debug, PartialEq)]
pub struct CoatingTables {
    transmittance: [f32; TABLE_SIZE],
    fdr_int: f32,
}

impl CoatingTables {
    pub fn new(distribution: &Microfacet, eta: f32) -> Self {
        let mut transmittance = [0.0; TABLE_SIZE];
        transmittance.copy_from_slice(&albedo_table(distribution, eta, Lobe::Transmission));
        let fdr_int =
            table_average(&albedo_table(distribution, 1.0 / eta, Lobe::Reflection)) as f32;
        CoatingTables {
            transmittance,
            fdr_int,
        }
    }
}

impl RoughPlastic {
    pub fn new(
        distribution: Microfacet,
        eta: f32,
        diffuse_reflectance: Spectrum,
        specular_reflectance: Spectrum,
        nonlinear: bool,
    ) -> Self {
        let tables = CoatingTables::new(&distribution, eta);
        Self::with_tables(
            distribution,
            eta,
            diffuse_reflectance,
            specular_reflectance,
            nonlinear,
            &tables,
        )
    }

    /// With the coating's tables already computed (for this `distribution` and `eta`).
    pub fn with_tables(
        distribution: Microfacet,
        eta: f32,
        diffuse_reflectance: Spectrum,
        specular_reflectance: Spectrum,
        nonlinear: bool,
        tables: &CoatingTables,
    ) -> Self {
        RoughPlastic {
            distribution,
            eta,
            diffuse_reflectance,
            specular_reflectance,
            nonlinear,
            transmittance: tables.transmittance,
            fdr_int: tables.fdr_int,
            specular_sampling_weight: specular_sampling_weight(
                specular_reflectance,
                diffuse_reflectance,
            ),
        }
    }

    /// T(μ), linearly interpolated.
    pub fn external_transmittance(&self, mu: f32) -> f32 {
        let x = mu.clamp(0.0, 1.0) * (TABLE_SIZE - 1) as f32;
        let i = (x as usize).min(TABLE_SIZE - 2);
        let t = x - i as f32;
        self.transmittance[i] * (1.0 - t) + self.transmittance[i + 1] * t
    }

    /// The coating's reflection lobe (white), f cos θo.
    fn specular_eval(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some(m) = (wi + wo).try_normalize() else {
            return 0.0;
        };
        let d = self.distribution.d(m);
        if d == 0.0 {
            return 0.0;
        }
        let g = self.distribution.g_eval(wi, wo, m);
        let f = fresnel_dielectric(wi.dot(m), self.eta).f;
        (f as f64 * d as f64 * g as f64 / (4.0 * wi.z as f64)) as f32
    }

    fn specular_pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some(m) = (wi + wo).try_normalize() else {
            return 0.0;
        };
        let dot = wo.dot(m);
        if dot <= 0.0 {
            return 0.0;
        }
        (self.distribution.pdf(wi, m) as f64 / (4.0 * dot as f64)) as f32
    }

    /// Probability of sampling the specular lobe, given the coating's transmittance T(cos θi).
    fn prob_specular(&self, t_i: f32) -> f32 {
        specular_lobe_probability(1.0 - t_i, t_i, self.specular_sampling_weight)
    }

    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let spec = self.specular_reflectance * self.specular_eval(wi, wo);
        let diff = diffuse_with_internal_scattering(
            self.diffuse_reflectance,
            self.fdr_int,
            self.nonlinear,
        );
        let t = self.external_transmittance(wi.z) * self.external_transmittance(wo.z);
        spec + diff * (t / (self.eta * self.eta) * FRAC_1_PI * wo.z)
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let ps = self.prob_specular(self.external_transmittance(wi.z));
        ps * self.specular_pdf(wi, wo) + (1.0 - ps) * square_to_cosine_hemisphere_pdf(wo)
    }

    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let ps = self.prob_specular(self.external_transmittance(wi.z));
        let wo = if u1 < ps {
            reflect(wi, self.distribution.sample(wi, u2)?.0)
        } else {
            square_to_cosine_hemisphere(u2)
        };
        if wo.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wi, wo);
        BsdfSample::smooth(wo, pdf, || self.eval(wi, wo), 1.0)
    }
}

/// The coating tables computed so far for a scene, by distribution and η.
#[derive(Default)]
struct Coatings(Vec<((Microfacet, f32), CoatingTables)>);

impl TablePlugin for RoughPlastic {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], cache: &mut PluginCache) -> Self {
        let distribution = Microfacet::from_params(v[0].x, v[1].x, v[1].x, v[2].x);
        let eta = (v[3].x / v[4].x) as f32;
        let coatings = &mut cache.get::<Coatings>().0;
        let tables = match coatings.iter().find(|(k, _)| *k == (distribution, eta)) {
            Some((_, t)) => t.clone(),
            None => {
                let t = CoatingTables::new(&distribution, eta);
                coatings.push(((distribution, eta), t.clone()));
                t
            }
        };
        RoughPlastic::with_tables(
            distribution,
            eta,
            crate::spectrum::from_rgb_f64(v[5]),
            crate::spectrum::from_rgb_f64(v[6]),
            v[7].x != 0.0,
            &tables,
        )
    }
}

impl super::BsdfModel for RoughPlastic {
    const NAME: &'static str = "roughplastic";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            5 => self.diffuse_reflectance = v,
            6 => self.specular_reflectance = v,
            _ => {}
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        RoughPlastic::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        RoughPlastic::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        RoughPlastic::sample(self, wi, u1, u2)
    }
}
