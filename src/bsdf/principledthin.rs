//! Mitsuba's `principledthin`: the thin-surface variant of the Disney BSDF (Burley 2015,
//! "Extending the Disney BRDF to a BSDF with Integrated Subsurface Scattering", §4 and
//! figure 15) as Mitsuba 3.9.1 implements it: an infinitely thin sheet, the same from both
//! sides (directions are mirrored to the side of wi), that does not bend light. With
//! s = spec_trans and t = diff_trans / 2 (diff_trans ranges over [0, 2]), f cos θo is the sum of
//!
//! - specular reflection: s · F D G / (4 cos θi), GGX of the roughness as in `principled`
//!   (see [`super::principled`]), F = lerp(F_d, S(base_color/lum · R0(η)), spec_tint) with
//!   F_d the exact dielectric Fresnel term of η = `eta` (a relative IOR) and S Schlick's
//!   approximation; the specular lobes exist only with spec_trans > 0;
//! - specular transmission: s · base_color (1 − F_d) D' G' / (4 cos θi) where wo is the
//!   mirror image, through the sheet, of a reflected direction: the half vector is that of
//!   wi and wo reflected back to wi's side, and D', G' use the roughness scaled by
//!   0.65 η − 0.35 (Burley 2015, figure 15);
//! - diffuse reflection: (1 − s)(1 − t) base_color/π · cos θo · lerp(f_d + f_r, f_ss,
//!   flatness) plus sheen (1 − s)(1 − t) sheen (1 − cos θd)^5 lerp(1, base_color/lum,
//!   sheen_tint) cos θo, as in `principled`;
//! - diffuse transmission: (1 − s) t base_color/π |cos θo|.
//!
//! Sampling picks, with probabilities ∝ s · specular_reflectance_rate / 2,
//! s · specular_transmittance_rate / 2, (1 − s)(1 − t) diffuse_reflectance_rate and
//! (1 − s) t diffuse_transmittance_rate (in that order on [0, 1)): GGX visible normals,
//! visible normals of the scaled distribution mirrored through the sheet, a cosine
//! hemisphere on wi's side, a cosine hemisphere on the other side. The relative IOR of every
//! sample is 1.

use super::fresnel::{fresnel_dielectric, reflect};
use super::microfacet::Microfacet;
use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::principled::{
    disney_diffuse, disney_ggx, facet_sides_agree, rate, schlick_r0, schlick_weight,
    schlick_weight_at, sheen_color, tint_color, weight, SHARED,
};
use super::{BsdfSample, Spectrum};
use crate::sampling::{square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf};
use crate::spectrum::ColorRole;
use glam::DVec3;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// `principledthin`'s parameters (Mitsuba 3.9.1's names and defaults), in the order of
/// [`PrincipledThinParams`]'s fields.
const PARAMS: &[ParamSpec] = &[
    SHARED[0],
    SHARED[1],
    SHARED[2],
    SHARED[3],
    SHARED[4],
    SHARED[5],
    SHARED[6],
    SHARED[7],
    ParamSpec::new(
        "eta",
        ParamKind::Number(ColorRole::Unbounded),
        1.5,
        "the sheet's relative IOR",
    ),
    weight(
        "diff_trans",
        0.0,
        "diffuse transmission, in [0, 2] (the model uses half)",
    ),
    rate(
        "specular_reflectance_sampling_rate",
        "sampling weight of the specular reflection",
    ),
    rate(
        "specular_transmittance_sampling_rate",
        "sampling weight of the specular transmission",
    ),
    rate(
        "diffuse_reflectance_sampling_rate",
        "sampling weight of the diffuse reflection",
    ),
    rate(
        "diffuse_transmittance_sampling_rate",
        "sampling weight of the diffuse transmission",
    ),
];

/// Mitsuba's `principledthin` parameters, with its defaults, as plain values at a shading
/// point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipledThinParams {
    pub base_color: Spectrum,
    pub roughness: f32,
    pub anisotropic: f32,
    pub spec_trans: f32,
    /// In [0, 2]: the model uses half of it.
    pub diff_trans: f32,
    /// Relative IOR of the sheet.
    pub eta: f32,
    pub spec_tint: f32,
    pub sheen: f32,
    pub sheen_tint: f32,
    pub flatness: f32,
    pub specular_reflectance_sampling_rate: f32,
    pub specular_transmittance_sampling_rate: f32,
    pub diffuse_reflectance_sampling_rate: f32,
    pub diffuse_transmittance_sampling_rate: f32,
}

impl Default for PrincipledThinParams {
    fn default() -> Self {
        PrincipledThinParams {
            base_color: Spectrum::splat(0.5),
            roughness: 0.5,
            anisotropic: 0.0,
            spec_trans: 0.0,
            diff_trans: 0.0,
            eta: 1.5,
            spec_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.0,
            flatness: 0.0,
            specular_reflectance_sampling_rate: 1.0,
            specular_transmittance_sampling_rate: 1.0,
            diffuse_reflectance_sampling_rate: 1.0,
            diffuse_transmittance_sampling_rate: 1.0,
        }
    }
}

#[derive(Clone, Debug)]
pub struct PrincipledThin {
    /// The parameters it was made from (textured ones are set at each shading point).
    pub params: PrincipledThinParams,
    pub base_color: Spectrum,
    pub roughness: f32,
    pub spec_trans: f32,
    /// Half of the `diff_trans` parameter.
    pub diff_trans: f32,
    pub eta: f32,
    pub spec_tint: f32,
    pub sheen: f32,
    pub sheen_tint: f32,
    pub flatness: f32,
    /// The reflection lobe's distribution.
    pub distribution: Microfacet,
    /// The transmission lobe's distribution (roughness scaled by 0.65 η − 0.35).
    pub transmission_distribution: Microfacet,
    /// Normalised lobe probabilities: specular reflection, specular transmission, diffuse
    /// reflection, diffuse transmission.
    probabilities: [f32; 4],
}

impl PrincipledThin {
    pub fn new(p: PrincipledThinParams) -> Self {
        let s = p.spec_trans;
        let t = 0.5 * p.diff_trans;
        let w = [
            s * p.specular_reflectance_sampling_rate / 2.0,
            s * p.specular_transmittance_sampling_rate / 2.0,
            p.diffuse_reflectance_sampling_rate * (1.0 - s) * (1.0 - t),
            p.diffuse_transmittance_sampling_rate * (1.0 - s) * t,
        ];
        let total: f32 = w.iter().sum();
        let probabilities = if total > 0.0 {
            w.map(|x| x / total)
        } else {
            [0.0; 4]
        };
        PrincipledThin {
            params: p,
            base_color: p.base_color,
            roughness: p.roughness,
            spec_trans: s,
            diff_trans: t,
            eta: p.eta,
            spec_tint: p.spec_tint,
            sheen: p.sheen,
            sheen_tint: p.sheen_tint,
            flatness: p.flatness,
            distribution: disney_ggx(p.roughness, p.anisotropic),
            transmission_distribution: disney_ggx(
                (0.65 * p.eta - 0.35) * p.roughness,
                p.anisotropic,
            ),
            probabilities,
        }
    }

    pub fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        wi.z != 0.0
    }

    pub fn is_transmissive(&self) -> bool {
        self.spec_trans > 0.0 || (self.diff_trans > 0.0 && self.spec_trans < 1.0)
    }

    /// Directions mirrored so that wi is on the front, and the half vector of wi and wo
    /// reflected back to wi's side.
    fn frame(wi: Vec3, wo: Vec3) -> (Vec3, Vec3, Option<Vec3>) {
        let s = if wi.z < 0.0 { -1.0 } else { 1.0 };
        let (wi, wo) = (wi * s, wo * s);
        let wo_r = Vec3::new(wo.x, wo.y, wo.z.abs());
        (wi, wo, (wi + wo_r).try_normalize())
    }

    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        if wi.z == 0.0 || wo.z == 0.0 {
            return Spectrum::ZERO;
        }
        let (wi, wo, wh) = Self::frame(wi, wo);
        let Some(wh) = wh else {
            return Spectrum::ZERO;
        };
        let (ci, co) = (wi.z, wo.z);
        let s = self.spec_trans;
        let mut value = Spectrum::ZERO;
        if co > 0.0 {
            if s > 0.0 && facet_sides_agree(wh, wi, wo, ci, true) {
                let wim = wi.dot(wh);
                let f = fresnel_dielectric(wim, self.eta).f;
                let tinted = tint_color(self.base_color) * schlick_r0(self.eta);
                let schlick = tinted + (Spectrum::ONE - tinted) * schlick_weight_at(wim, self.eta);
                let fresnel = Spectrum::splat(f) + (schlick - Spectrum::splat(f)) * self.spec_tint;
                let d = self.distribution.d(wh);
                let g = self.distribution.g_eval(wi, wo, wh);
                value += fresnel * (s * d * g / (4.0 * ci));
            }
            if s < 1.0 && self.diff_trans < 1.0 {
                let cos_d = wh.dot(wo);
                let k = (1.0 - s) * (1.0 - self.diff_trans);
                let fd = disney_diffuse(ci, co, cos_d, self.roughness, self.flatness);
                value += self.base_color * (k * co * FRAC_1_PI * fd);
                if self.sheen > 0.0 {
                    value += sheen_color(self.base_color, self.sheen_tint)
                        * (self.sheen * k * schlick_weight(cos_d.abs()) * co);
                }
            }
        } else {
            if s > 0.0 && facet_sides_agree(wh, wi, wo, ci, false) {
                let f = fresnel_dielectric(wi.dot(wh), self.eta).f;
                let d = self.transmission_distribution.d(wh);
                let g = self.transmission_distribution.g_eval(wi, wo, wh);
                value += self.base_color * (s * (1.0 - f) * d * g / (4.0 * ci));
            }
            if s < 1.0 && self.diff_trans > 0.0 {
                value += self.base_color * ((1.0 - s) * self.diff_trans * FRAC_1_PI * -co);
            }
        }
        value
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z == 0.0 || wo.z == 0.0 {
            return 0.0;
        }
        let (wi, wo, wh) = Self::frame(wi, wo);
        let [p_sr, p_st, p_dr, p_dt] = self.probabilities;
        let reflection = wo.z > 0.0;
        let mut pdf = if reflection {
            p_dr * square_to_cosine_hemisphere_pdf(wo)
        } else {
            p_dt * square_to_cosine_hemisphere_pdf(-wo)
        };
        if let Some(wh) = wh {
            if self.spec_trans > 0.0 && facet_sides_agree(wh, wi, wo, wi.z, reflection) {
                // the reflection Jacobian, for wo reflected back to wi's side
                let wo_r = Vec3::new(wo.x, wo.y, wo.z.abs());
                let dwh_dwo = 1.0 / (4.0 * wo_r.dot(wh)).abs();
                pdf += if reflection {
                    p_sr * self.distribution.pdf(wi, wh)
                } else {
                    p_st * self.transmission_distribution.pdf(wi, wh)
                } * dwh_dwo;
            }
        }
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z == 0.0 || !wi.is_finite() {
            return None;
        }
        let sign = if wi.z < 0.0 { -1.0 } else { 1.0 };
        let wi_f = wi * sign;
        let [p_sr, p_st, p_dr, p_dt] = self.probabilities;
        let wo = if u1 < p_sr {
            let (m, _) = self.distribution.sample(wi_f, u2)?;
            let wo = reflect(wi_f, m);
            (wo.z > 0.0 && facet_sides_agree(m, wi_f, wo, wi_f.z, true)).then_some(wo)?
        } else if u1 < p_sr + p_st {
            let (m, _) = self.transmission_distribution.sample(wi_f, u2)?;
            let r = reflect(wi_f, m);
            let wo = Vec3::new(r.x, r.y, -r.z);
            (wo.z < 0.0 && facet_sides_agree(m, wi_f, wo, wi_f.z, false)).then_some(wo)?
        } else if u1 < p_sr + p_st + p_dr {
            square_to_cosine_hemisphere(u2)
        } else if p_dt > 0.0 {
            -square_to_cosine_hemisphere(u2)
        } else {
            return None;
        };
        let wo = wo * sign;
        let pdf = self.pdf(wi, wo);
        BsdfSample::smooth(wo, pdf, || self.eval(wi, wo), 1.0)
    }
}

impl TablePlugin for PrincipledThin {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        PrincipledThin::new(PrincipledThinParams {
            base_color: crate::spectrum::from_rgb_f64(v[0]),
            roughness: v[1].x as f32,
            anisotropic: v[2].x as f32,
            spec_trans: v[3].x as f32,
            sheen: v[4].x as f32,
            sheen_tint: v[5].x as f32,
            flatness: v[6].x as f32,
            spec_tint: v[7].x as f32,
            eta: v[8].x as f32,
            diff_trans: v[9].x as f32,
            specular_reflectance_sampling_rate: v[10].x as f32,
            specular_transmittance_sampling_rate: v[11].x as f32,
            diffuse_reflectance_sampling_rate: v[12].x as f32,
            diffuse_transmittance_sampling_rate: v[13].x as f32,
        })
    }
}

impl super::BsdfModel for PrincipledThin {
    const NAME: &'static str = "principledthin";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            0 => self.params.base_color = v,
            1 => self.params.roughness = v.x,
            2 => self.params.anisotropic = v.x,
            3 => self.params.spec_trans = v.x,
            4 => self.params.sheen = v.x,
            5 => self.params.sheen_tint = v.x,
            6 => self.params.flatness = v.x,
            7 => self.params.spec_tint = v.x,
            8 => self.params.eta = v.x,
            9 => self.params.diff_trans = v.x,
            _ => {}
        }
    }

    /// The lobe weights, roughness and η depend on the parameters: made anew, as Mitsuba
    /// evaluates them at each shading point.
    fn params_set(&mut self) {
        *self = PrincipledThin::new(self.params);
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        PrincipledThin::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        PrincipledThin::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        PrincipledThin::sample(self, wi, u1, u2)
    }

    #[inline]
    fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        PrincipledThin::has_smooth_lobe(self, wi)
    }

    fn is_transmissive(&self) -> bool {
        PrincipledThin::is_transmissive(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;
    use crate::sampling::square_to_uniform_sphere;

    fn configurations() -> Vec<PrincipledThinParams> {
        let d = PrincipledThinParams::default();
        vec![
            d,
            PrincipledThinParams {
                base_color: crate::spectrum::rgb(0.7, 0.1, 0.1),
                roughness: 0.15,
                spec_tint: 0.1,
                anisotropic: 0.5,
                spec_trans: 0.8,
                diff_trans: 0.3,
                eta: 1.33,
                sheen: 0.5,
                sheen_tint: 0.3,
                flatness: 0.5,
                ..d
            },
            PrincipledThinParams {
                spec_trans: 1.0,
                roughness: 0.4,
                ..d
            },
            PrincipledThinParams {
                diff_trans: 2.0,
                ..d
            },
        ]
    }

    #[test]
    fn principledthin_sample_weight_is_eval_over_pdf() {
        let mut s = SampleStream::new(1, 2, 3);
        for p in configurations() {
            let b = PrincipledThin::new(p);
            for _ in 0..2000 {
                let wi = square_to_uniform_sphere(s.next_2d());
                let Some(bs) = b.sample(wi, s.next_1d(), s.next_2d()) else {
                    continue;
                };
                let (f, pdf) = (b.eval(wi, bs.wo), b.pdf(wi, bs.wo));
                assert!(!bs.delta && pdf > 0.0 && bs.eta == 1.0);
                assert!((bs.pdf - pdf).abs() <= 1e-6 * pdf, "{p:?}: {bs:?} vs {pdf}");
                let w = f / pdf;
                assert!(
                    (bs.weight - w).abs().max_element() <= 1e-5 * w.max_element(),
                    "{p:?}: {bs:?} vs {w}"
                );
            }
        }
    }

    #[test]
    fn principledthin_is_symmetric_and_pdf_covers_eval() {
        let mut s = SampleStream::new(7, 8, 9);
        for p in configurations() {
            let b = PrincipledThin::new(p);
            for _ in 0..20_000 {
                let wi = square_to_uniform_sphere(s.next_2d());
                let wo = square_to_uniform_sphere(s.next_2d());
                let f = b.eval(wi, wo);
                assert_eq!(f, b.eval(-wi, -wo));
                assert_eq!(b.pdf(wi, wo), b.pdf(-wi, -wo));
                if f.max_element() > 0.0 {
                    assert!(b.pdf(wi, wo) > 0.0, "{p:?}: {wi} {wo}");
                }
            }
        }
    }

    /// A `<float>` spec_trans above 1 (which Mitsuba accepts) would give the diffuse lobes a
    /// negative weight 1 − s; Mitsuba masks them off (`spec_trans < 1`), and so does
    /// penumbra: eval stays non-negative and equals the specular lobes alone, i.e. the value
    /// of the same material with the base colour black (it scales only the diffuse lobes and
    /// the transmission, which is below the surface here). Its samples keep finite,
    /// non-negative weights.
    #[test]
    fn spec_trans_above_one_masks_the_diffuse_lobes_off() {
        let over = PrincipledThinParams {
            spec_trans: 1.5,
            sheen: 0.5,
            ..PrincipledThinParams::default()
        };
        let (b, black) = (
            PrincipledThin::new(over),
            PrincipledThin::new(PrincipledThinParams {
                base_color: Spectrum::ZERO,
                spec_tint: 0.0,
                sheen: 0.0,
                ..over
            }),
        );
        let mut s = SampleStream::new(3, 1, 4);
        let mut lit = 0;
        for _ in 0..2000 {
            let wi = square_to_uniform_sphere(s.next_2d());
            let wo = square_to_uniform_sphere(s.next_2d());
            if wi.z * wo.z <= 0.0 {
                continue;
            }
            let f = b.eval(wi, wo);
            assert!(f.min_element() >= 0.0, "{wi} {wo}: {f}");
            assert_eq!(f, black.eval(wi, wo), "{wi} {wo}");
            lit += (f.max_element() > 0.0) as usize;
        }
        assert!(lit > 500, "{lit}");
        for _ in 0..2000 {
            let wi = square_to_uniform_sphere(s.next_2d());
            if let Some(bs) = b.sample(wi, s.next_1d(), s.next_2d()) {
                assert!(
                    bs.weight.is_finite() && bs.weight.min_element() >= 0.0,
                    "{bs:?}"
                );
            }
        }
    }
}
