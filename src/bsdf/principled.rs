//! Mitsuba's `principled`: the Disney BSDF as Mitsuba 3.9.1 implements it, after Burley 2012,
//! "Physically Based Shading at Disney" (SIGGRAPH course notes), and Burley 2015, "Extending
//! the Disney BRDF to a BSDF with Integrated Subsurface Scattering" (without the subsurface
//! and volumetric parts, which Mitsuba leaves out too). With brdf = (1 − metallic)(1 −
//! spec_trans) and bsdf = (1 − metallic) spec_trans, f cos θo is the sum of
//!
//! - main specular reflection: F D G / (4 |cos θi|) with an anisotropic GGX D and separable
//!   Smith G (α_x = max(0.001, r² / a), α_y = max(0.001, r² a), a = √(1 − 0.9 anisotropic),
//!   r = roughness; α_x along the shading frame's tangent, which follows dp/du as Mitsuba's).
//!   From the front, F = (1 − metallic)(1 − spec_tint) F_d + metallic S(base_color) +
//!   (1 − metallic) spec_tint S(base_color / lum · R0(η)), where F_d is the exact dielectric
//!   Fresnel term of η, S(F0) Schlick's approximation F0 + (1 − F0)(1 − cos)^5 (with the
//!   transmitted cosine when the incident side is the denser one) and lum the luminance of
//!   base_color; from the back F = bsdf F_d (no tint, no metal);
//! - main specular transmission (both sides): √base_color · bsdf times Walter et al. 2007's
//!   rough dielectric transmission (eq. 21) with 1 − F_d, in radiance mode (scaled by
//!   (η_i/η_o)²), the same D and G;
//! - clearcoat (front only): 0.25 clearcoat · S_η(0.04) · D_GTR1(m) · G1(wi) G1(wo) · |cos θo|,
//!   with Burley's normalised GTR1 (γ = 1) of α = lerp(0.1, 0.001, clearcoat_gloss) and the
//!   GGX Smith G1 of α = 0.25. (Mitsuba's clearcoat has no 1/(4 cos θi cos θo): Burley's
//!   BRDF Explorer folds it into its G, Mitsuba's G1 does not; this follows Mitsuba.)
//! - diffuse (front only): brdf · base_color/π · |cos θo| · lerp(f_d + f_r, f_ss, flatness),
//!   Burley's f_d = (1 − F_i/2)(1 − F_o/2), retro-reflection f_r = R (F_o + F_i + F_o F_i
//!   (R − 1)), R = 2 roughness cos²θd, and the Hanrahan–Krueger-inspired "fake subsurface"
//!   f_ss = 1.25 (F_ss (1/(cos θi + cos θo) − 0.5) + 0.5), F_ss = lerp(1, R/2, F_o)
//!   lerp(1, R/2, F_i), with F_x = (1 − cos θx)^5 and θd the angle of wo to the half vector;
//! - sheen (front only): sheen (1 − metallic) (1 − cos θd)^5 lerp(1, base_color/lum,
//!   sheen_tint) |cos θo|.
//!
//! η is `eta` or, if only `specular` is given, the IOR whose normal-incidence reflectance is
//! 0.08 specular: η = 2 / (1 − √(0.08 specular)) − 1 (specular 0.5 → η = 1.5).
//!
//! Sampling (one lobe per sample, the weight eval / pdf of the whole mixture): from the front
//! the lobes are picked with probabilities ∝ brdf · diffuse_rate (cosine hemisphere),
//! 0.25 clearcoat · clearcoat_rate (GTR1 normals D cos θm), and main_specular_rate split
//! between reflection, 1 − bsdf (1 − F_d(wi·m)), and transmission, bsdf (1 − F_d(wi·m)),
//! where m is a GGX visible normal; from the back only the specular lobe, reflection with
//! probability F_d(wi·m) and transmission otherwise. Reflection lobes are two-sided only
//! through the specular lobes: seen from behind without transmission (bsdf = 0) the BSDF
//! is black.
//!
//! Where Mitsuba's variants differ, this follows the vectorised ones (llvm_ad_rgb, which
//! the reference renders use): with spec_trans = 1 (so brdf = 0) the sheen lobe still
//! contributes; scalar_rgb skips it with the diffuse lobe. And Mitsuba's `pdf` seen from
//! behind without transmission returns the specular reflection density although `sample`
//! never produces anything there and `eval` is 0; here it is 0, the density of `sample`.

use super::fresnel::{fresnel_dielectric, reflect, refract};
use super::microfacet::{Microfacet, MicrofacetType};
use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::roughdielectric::half_vector;
use super::{BsdfSample, Spectrum};
use crate::sampling::{square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf};
use crate::spectrum::luminance;
use crate::spectrum::ColorRole;
use glam::DVec3;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// `principled`'s parameters (Mitsuba 3.9.1's names and defaults), in the order of
/// [`PrincipledParams`]'s fields.
const PARAMS: &[ParamSpec] = &[
    SHARED[0],
    SHARED[1],
    SHARED[2],
    ParamSpec::new(
        "has_spec_trans",
        ParamKind::Given("spec_trans"),
        0.0,
        "whether spec_trans is given (a texture or not 0): η = 1 and specular = 0 are nudged",
    ),
    SHARED[3],
    SHARED[4],
    SHARED[5],
    SHARED[6],
    SHARED[7],
    weight("metallic", 0.0, "blend towards a metal"),
    weight("clearcoat", 0.0, "weight of the clearcoat lobe"),
    weight("clearcoat_gloss", 0.0, "glossiness of the clearcoat"),
    ParamSpec::new(
        "eta",
        ParamKind::Exclusive("specular"),
        0.0,
        "the relative IOR (else the one `specular` stands for)",
    ),
    ParamSpec::new(
        "specular",
        ParamKind::Float,
        0.5,
        "normal-incidence reflectance control, as the IOR it stands for",
    )
    .range(0.0, 1.0),
    rate(
        "diffuse_reflectance_sampling_rate",
        "sampling weight of the diffuse lobe",
    ),
    rate(
        "main_specular_sampling_rate",
        "sampling weight of the main specular lobes",
    ),
    rate(
        "clearcoat_sampling_rate",
        "sampling weight of the clearcoat lobe",
    ),
];

/// A one-value parameter of the Disney model, texture allowed (read as a reflectance, as
/// Mitsuba reads them).
pub(super) const fn weight(name: &'static str, default: f64, doc: &'static str) -> ParamSpec {
    ParamSpec::new(
        name,
        ParamKind::Number(ColorRole::Reflectance),
        default,
        doc,
    )
}

/// A lobe's sampling rate: a plain number ≥ 0 (default 1).
pub(super) const fn rate(name: &'static str, doc: &'static str) -> ParamSpec {
    ParamSpec::new(name, ParamKind::Float, 1.0, doc).range(0.0, f64::INFINITY)
}

/// The parameters `principled` and `principledthin` share, in principledthin's order.
pub(super) const SHARED: [ParamSpec; 8] = [
    ParamSpec::new(
        "base_color",
        ParamKind::Color(ColorRole::Reflectance),
        0.5,
        "the base colour",
    ),
    weight(
        "roughness",
        0.5,
        "roughness of the specular and diffuse lobes",
    ),
    weight("anisotropic", 0.0, "anisotropy of the specular lobes"),
    weight("spec_trans", 0.0, "weight of the specular transmission"),
    weight("sheen", 0.0, "weight of the sheen lobe"),
    weight(
        "sheen_tint",
        0.0,
        "how much the sheen takes the base colour",
    ),
    weight(
        "flatness",
        0.0,
        "blend of the diffuse lobe towards the subsurface approximation",
    ),
    weight(
        "spec_tint",
        0.0,
        "how much the specular reflection takes the base colour",
    ),
];

/// Mitsuba's `principled` parameters, with its defaults, as plain values at a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipledParams {
    pub base_color: Spectrum,
    pub roughness: f32,
    pub anisotropic: f32,
    pub metallic: f32,
    pub spec_trans: f32,
    /// Whether `spec_trans` is given in the scene (a texture, or a float other than 0):
    /// Mitsuba then nudges η = 1 to 1.001 and specular = 0 to 0.001. A non-zero `spec_trans`
    /// implies it.
    pub has_spec_trans: bool,
    /// Used when `eta` is `None` (Mitsuba rejects scenes that give both).
    pub specular: f32,
    /// Interior / exterior IOR.
    pub eta: Option<f32>,
    pub spec_tint: f32,
    pub sheen: f32,
    pub sheen_tint: f32,
    pub flatness: f32,
    pub clearcoat: f32,
    pub clearcoat_gloss: f32,
    pub diffuse_reflectance_sampling_rate: f32,
    pub main_specular_sampling_rate: f32,
    /// Mitsuba's documentation says 0 by default; its code (which this follows) uses 1.
    pub clearcoat_sampling_rate: f32,
}

impl Default for PrincipledParams {
    fn default() -> Self {
        PrincipledParams {
            base_color: Spectrum::splat(0.5),
            roughness: 0.5,
            anisotropic: 0.0,
            metallic: 0.0,
            spec_trans: 0.0,
            has_spec_trans: false,
            specular: 0.5,
            eta: None,
            spec_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.0,
            flatness: 0.0,
            clearcoat: 0.0,
            clearcoat_gloss: 0.0,
            diffuse_reflectance_sampling_rate: 1.0,
            main_specular_sampling_rate: 1.0,
            clearcoat_sampling_rate: 1.0,
        }
    }
}

impl PrincipledParams {
    /// The relative IOR η Mitsuba uses: `eta`, or the one `specular` stands for.
    pub fn relative_ior(&self) -> f32 {
        let has_spec_trans = self.has_spec_trans || self.spec_trans != 0.0;
        match self.eta {
            Some(eta) if has_spec_trans && eta == 1.0 => 1.001,
            Some(eta) => eta,
            None => {
                let specular = if has_spec_trans && self.specular == 0.0 {
                    1e-3
                } else {
                    self.specular
                };
                2.0 / (1.0 - (0.08 * specular).sqrt()) - 1.0
            }
        }
    }
}

/// Schlick's weight (1 − cos)^5, with cos clamped to [0, 1].
#[inline]
pub(super) fn schlick_weight(cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// The weight w of Schlick's approximation F0 + (1 − F0) w at the signed cosine `cos_theta_i`
/// to the microfacet normal of an interface of relative IOR `eta`: (1 − |cos θi|)^5 from the
/// rarer side, (1 − cos θt)^5 from the denser one (1 beyond the critical angle), as Mitsuba.
/// Index-matched (η = 1: cos θt = |cos θi|) takes the first form, which is exact; the second
/// would compute cos θt² = 1 − (1 − cos²θi) and lose a grazing cos θi < 3.5e-4 entirely.
#[inline]
pub(super) fn schlick_weight_at(cos_theta_i: f32, eta: f32) -> f32 {
    let (eta_it, eta_ti) = if cos_theta_i >= 0.0 {
        (eta, 1.0 / eta)
    } else {
        (1.0 / eta, eta)
    };
    if eta_it >= 1.0 {
        schlick_weight(cos_theta_i.abs())
    } else {
        let cos_t2 = 1.0 - (1.0 - cos_theta_i * cos_theta_i) * eta_ti * eta_ti;
        schlick_weight(cos_t2.max(0.0).sqrt())
    }
}

/// Normal-incidence reflectance ((η − 1)/(η + 1))².
#[inline]
pub(super) fn schlick_r0(eta: f32) -> f32 {
    let r = (eta - 1.0) / (eta + 1.0);
    r * r
}

/// base_color / luminance (white for a black base), the hue the tints blend towards.
#[inline]
pub(super) fn tint_color(base_color: Spectrum) -> Spectrum {
    let lum = luminance(base_color);
    if lum > 0.0 {
        base_color / lum
    } else {
        Spectrum::ONE
    }
}

/// The main lobes' GGX distribution: Burley's roughness² mapping with the anisotropic
/// aspect √(1 − 0.9 anisotropic), α ≥ 0.001, visible-normal sampling.
pub(super) fn disney_ggx(roughness: f32, anisotropic: f32) -> Microfacet {
    let r2 = roughness * roughness;
    let aspect = (1.0 - 0.9 * anisotropic).sqrt();
    Microfacet::new(
        MicrofacetType::Ggx,
        (r2 / aspect).max(0.001),
        (r2 * aspect).max(0.001),
        true,
    )
}

/// Mitsuba's check that the microfacet `m` (oriented to the side of `wi`, whose macro cosine
/// is `cos_theta_i`) faces `wi`, and faces `wo` (reflection) or faces away from it
/// (transmission).
#[inline]
pub(super) fn facet_sides_agree(
    m: Vec3,
    wi: Vec3,
    wo: Vec3,
    cos_theta_i: f32,
    reflection: bool,
) -> bool {
    let m = if cos_theta_i < 0.0 { -m } else { m };
    wi.dot(m) > 0.0
        && if reflection {
            wo.dot(m) > 0.0
        } else {
            wo.dot(m) < 0.0
        }
}

/// Burley's diffuse with retro-reflection, blended by `flatness` with the fake subsurface
/// term: the factor of base_color/π · |cos θo| (see the module documentation).
#[inline]
pub(super) fn disney_diffuse(
    cos_i: f32,
    cos_o: f32,
    cos_d: f32,
    roughness: f32,
    flatness: f32,
) -> f32 {
    let (fi, fo) = (schlick_weight(cos_i), schlick_weight(cos_o));
    let f_diff = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo);
    let rr = 2.0 * roughness * cos_d * cos_d;
    let f_retro = rr * (fo + fi + fo * fi * (rr - 1.0));
    if flatness == 0.0 {
        return f_diff + f_retro;
    }
    let fss90 = 0.5 * rr;
    let fss = (1.0 + (fss90 - 1.0) * fo) * (1.0 + (fss90 - 1.0) * fi);
    let f_ss = 1.25 * (fss * (1.0 / (cos_o + cos_i) - 0.5) + 0.5);
    let base = f_diff + f_retro;
    base + (f_ss - base) * flatness
}

/// The sheen colour lerp(1, base_color/lum, sheen_tint).
#[inline]
pub(super) fn sheen_color(base_color: Spectrum, sheen_tint: f32) -> Spectrum {
    Spectrum::ONE + (tint_color(base_color) - Spectrum::ONE) * sheen_tint
}

/// Burley's GTR1 ("Berry") distribution of the clearcoat, D(m) = (α² − 1) /
/// (π ln α² (1 + (α² − 1) cos²θm)), normalised so that ∫ D cos θm dω = 1, sampled as
/// D cos θm (Burley 2012, appendix B).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Gtr1 {
    alpha: f32,
}

impl Gtr1 {
    fn d(&self, m: Vec3) -> f32 {
        let a2 = self.alpha * self.alpha;
        let c2 = m.z * m.z;
        let r = (a2 - 1.0) / (PI * crate::math::lnf(a2) * (1.0 + (a2 - 1.0) * c2));
        if r * m.z > 1e-20 {
            r
        } else {
            0.0
        }
    }

    fn pdf(&self, m: Vec3) -> f32 {
        if m.z < 0.0 {
            0.0
        } else {
            m.z * self.d(m)
        }
    }

    fn sample(&self, u: Vec2) -> Vec3 {
        let a2 = self.alpha * self.alpha;
        let (sin_phi, cos_phi) = crate::math::sin_cosf(2.0 * PI * u.x);
        let cos2 = (1.0 - a2.powf(1.0 - u.y)) / (1.0 - a2);
        let sin_t = (1.0 - cos2).max(0.0).sqrt();
        Vec3::new(cos_phi * sin_t, sin_phi * sin_t, cos2.max(0.0).sqrt())
    }
}

/// The clearcoat's shadowing–masking: GGX Smith G1 of α = 0.25 (Burley 2012).
const CLEARCOAT_G: Microfacet = Microfacet {
    kind: MicrofacetType::Ggx,
    alpha_u: 0.25,
    alpha_v: 0.25,
    sample_visible: true,
};

#[derive(Clone, Debug)]
pub struct Principled {
    /// The parameters it was made from (textured ones are set at each shading point).
    pub params: PrincipledParams,
    pub base_color: Spectrum,
    pub roughness: f32,
    pub metallic: f32,
    pub spec_tint: f32,
    pub sheen: f32,
    pub sheen_tint: f32,
    pub flatness: f32,
    pub clearcoat: f32,
    /// Relative IOR (interior / exterior).
    pub eta: f32,
    /// Weight of the diffuse-like lobes, (1 − metallic)(1 − spec_trans).
    pub brdf: f32,
    /// Weight of the transmission lobe, (1 − metallic) spec_trans.
    pub bsdf: f32,
    /// The main specular lobes' distribution.
    pub distribution: Microfacet,
    clearcoat_distribution: Gtr1,
    diffuse_rate: f32,
    specular_rate: f32,
    clearcoat_rate: f32,
}

/// Lobe selection probabilities at a direction pair: (specular reflection, specular
/// transmission, clearcoat, diffuse), normalised.
struct LobeProbabilities {
    spec_reflect: f32,
    spec_trans: f32,
    clearcoat: f32,
    diffuse: f32,
}

impl Principled {
    pub fn new(p: PrincipledParams) -> Self {
        let brdf = (1.0 - p.metallic) * (1.0 - p.spec_trans);
        let bsdf = (1.0 - p.metallic) * p.spec_trans;
        Principled {
            params: p,
            base_color: p.base_color,
            roughness: p.roughness,
            metallic: p.metallic,
            spec_tint: p.spec_tint,
            sheen: p.sheen,
            sheen_tint: p.sheen_tint,
            flatness: p.flatness,
            clearcoat: p.clearcoat,
            eta: p.relative_ior(),
            brdf,
            bsdf,
            distribution: disney_ggx(p.roughness, p.anisotropic),
            clearcoat_distribution: Gtr1 {
                alpha: 0.1 + (0.001 - 0.1) * p.clearcoat_gloss,
            },
            diffuse_rate: p.diffuse_reflectance_sampling_rate,
            specular_rate: p.main_specular_sampling_rate,
            clearcoat_rate: p.clearcoat_sampling_rate,
        }
    }

    /// Whether `sample` produces anything for incidence from this side.
    fn sees(&self, wi: Vec3) -> bool {
        wi.z > 0.0 || (wi.z < 0.0 && self.bsdf > 0.0)
    }

    pub fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        self.sees(wi)
    }

    pub fn is_transmissive(&self) -> bool {
        self.bsdf > 0.0
    }

    /// Unnormalised front-side weights of (diffuse, clearcoat, specular); the specular one
    /// is split by the Fresnel term of the sampled microfacet.
    fn front_weights(&self) -> (f32, f32, f32) {
        (
            self.brdf * self.diffuse_rate,
            0.25 * self.clearcoat * self.clearcoat_rate,
            self.specular_rate,
        )
    }

    /// Mitsuba's lobe probabilities given the dielectric Fresnel term `f` at the half vector.
    fn probabilities(&self, front: bool, f: f32) -> LobeProbabilities {
        let p = if front {
            let (d, c, s) = self.front_weights();
            LobeProbabilities {
                spec_reflect: s * (1.0 - self.bsdf * (1.0 - f)),
                spec_trans: s * self.bsdf * (1.0 - f),
                clearcoat: c,
                diffuse: d,
            }
        } else {
            LobeProbabilities {
                spec_reflect: f,
                spec_trans: 1.0 - f,
                clearcoat: 0.0,
                diffuse: 0.0,
            }
        };
        let total = p.spec_reflect + p.spec_trans + p.clearcoat + p.diffuse;
        // zero sampling rates: nothing is sampled
        let inv = if total > 0.0 { 1.0 / total } else { 0.0 };
        LobeProbabilities {
            spec_reflect: p.spec_reflect * inv,
            spec_trans: p.spec_trans * inv,
            clearcoat: p.clearcoat * inv,
            diffuse: p.diffuse * inv,
        }
    }

    /// The main specular Fresnel term for reflection at `cos_theta_i` = wi·m.
    fn specular_fresnel(&self, f_dielectric: f32, cos_theta_i: f32, front: bool) -> Spectrum {
        if !front {
            return Spectrum::splat(self.bsdf * f_dielectric);
        }
        let w = schlick_weight_at(cos_theta_i, self.eta);
        let schlick = |f0: Spectrum| f0 + (Spectrum::ONE - f0) * w;
        let eta_it = if cos_theta_i >= 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let metal = self.metallic * schlick(self.base_color);
        let tinted = (1.0 - self.metallic)
            * self.spec_tint
            * schlick(tint_color(self.base_color) * schlick_r0(eta_it));
        Spectrum::splat((1.0 - self.metallic) * (1.0 - self.spec_tint) * f_dielectric)
            + metal
            + tinted
    }

    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        let (ci, co) = (wi.z, wo.z);
        let Some((wh, eta_path, is_reflection)) = half_vector(wi, wo, self.eta) else {
            return Spectrum::ZERO;
        };
        let front = ci > 0.0;
        let wim = wi.dot(wh);
        let f = fresnel_dielectric(wim, self.eta).f;
        let mut value = Spectrum::ZERO;
        if is_reflection {
            if facet_sides_agree(wh, wi, wo, ci, true) {
                if f > 0.0 {
                    let d = self.distribution.d(wh);
                    let g = self.distribution.g_eval(wi, wo, wh);
                    value += self.specular_fresnel(f, wim, front) * (d * g / (4.0 * ci.abs()));
                }
                if front && self.clearcoat > 0.0 {
                    let fcc = 0.04 + 0.96 * schlick_weight_at(wim, self.eta);
                    let dcc = self.clearcoat_distribution.d(wh);
                    let gcc = CLEARCOAT_G.g_eval(wi, wo, wh);
                    value += Spectrum::splat(self.clearcoat * 0.25 * fcc * dcc * gcc * co.abs());
                }
            }
            if front {
                let cos_d = wh.dot(wo);
                if self.brdf > 0.0 {
                    let fd = disney_diffuse(ci, co, cos_d, self.roughness, self.flatness);
                    value += self.base_color * (self.brdf * co * FRAC_1_PI * fd);
                }
                if self.sheen > 0.0 && 1.0 - self.metallic > 0.0 {
                    value += sheen_color(self.base_color, self.sheen_tint)
                        * (self.sheen
                            * (1.0 - self.metallic)
                            * schlick_weight(cos_d.abs())
                            * co.abs());
                }
            }
        } else if self.bsdf > 0.0 && f < 1.0 && facet_sides_agree(wh, wi, wo, ci, false) {
            let d = self.distribution.d(wh);
            let g = self.distribution.g_eval(wi, wo, wh);
            let wom = wo.dot(wh);
            let denom = wim + eta_path * wom;
            let t = (1.0 - f) * d * g * (wim * wom).abs() / (ci.abs() * denom * denom);
            value += self.base_color.max(Spectrum::ZERO).map(f32::sqrt) * (self.bsdf * t);
        }
        value
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let ci = wi.z;
        if !self.sees(wi) {
            return 0.0;
        }
        let Some((wh, eta_path, is_reflection)) = half_vector(wi, wo, self.eta) else {
            return 0.0;
        };
        let front = ci > 0.0;
        let (wim, wom) = (wi.dot(wh), wo.dot(wh));
        let p = self.probabilities(front, fresnel_dielectric(wim, self.eta).f);
        let wi_up = if front { wi } else { -wi };
        let pdf = if is_reflection {
            let mut pdf = p.diffuse * square_to_cosine_hemisphere_pdf(wo);
            if facet_sides_agree(wh, wi, wo, ci, true) {
                let dwh_dwo = 1.0 / (4.0 * wom.abs());
                pdf += p.spec_reflect * self.distribution.pdf(wi_up, wh) * dwh_dwo;
                if p.clearcoat > 0.0 {
                    pdf += p.clearcoat * self.clearcoat_distribution.pdf(wh) * dwh_dwo;
                }
            }
            pdf
        } else if p.spec_trans > 0.0 && facet_sides_agree(wh, wi, wo, ci, false) {
            let denom = wim + eta_path * wom;
            let dwh_dwo = (eta_path * eta_path * wom / (denom * denom)).abs();
            p.spec_trans * self.distribution.pdf(wi_up, wh) * dwh_dwo
        } else {
            0.0
        };
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        let ci = wi.z;
        if !self.sees(wi) || !wi.is_finite() {
            return None;
        }
        let front = ci > 0.0;
        // Mitsuba's order on [0, 1): diffuse, clearcoat, transmission, reflection. From the
        // front the first two do not depend on the microfacet's Fresnel term.
        let (mut p_diffuse, mut p_clearcoat, mut p_spec) = (0.0, 0.0, 1.0);
        if front {
            let (d, c, s) = self.front_weights();
            let inv = 1.0 / (d + c + s);
            (p_diffuse, p_clearcoat, p_spec) = (d * inv, c * inv, s * inv);
        }
        // Each lobe keeps only directions on its side whose microfacet faces both ways
        // consistently (the clearcoat's normals are not visible-sampled and may face away).
        let reflected = |wo: Vec3, m: Vec3| {
            (ci * wo.z > 0.0 && facet_sides_agree(m, wi, wo, ci, true)).then_some((wo, 1.0))
        };
        let (wo, eta) = if u1 < p_diffuse {
            let wo = square_to_cosine_hemisphere(u2);
            (wo.z > 0.0).then_some((wo, 1.0))?
        } else if u1 < p_diffuse + p_clearcoat {
            let m = self.clearcoat_distribution.sample(u2);
            reflected(reflect(wi, m), m)?
        } else {
            let wi_up = if front { wi } else { -wi };
            let (m, _) = self.distribution.sample(wi_up, u2)?;
            let fr = fresnel_dielectric(wi.dot(m), self.eta);
            let p_trans = if front {
                p_spec * self.bsdf * (1.0 - fr.f)
            } else {
                1.0 - fr.f
            };
            if u1 < p_diffuse + p_clearcoat + p_trans {
                let wo = refract(wi, m, fr.cos_theta_t, fr.eta_ti);
                (ci * wo.z < 0.0 && facet_sides_agree(m, wi, wo, ci, false))
                    .then_some((wo, fr.eta_it))?
            } else {
                reflected(reflect(wi, m), m)?
            }
        };
        let pdf = self.pdf(wi, wo);
        BsdfSample::smooth(wo, pdf, || self.eval(wi, wo), eta)
    }
}

impl TablePlugin for Principled {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        Principled::new(PrincipledParams {
            base_color: crate::spectrum::from_rgb_f64(v[0]),
            roughness: v[1].x as f32,
            anisotropic: v[2].x as f32,
            has_spec_trans: v[3].x != 0.0,
            spec_trans: v[4].x as f32,
            sheen: v[5].x as f32,
            sheen_tint: v[6].x as f32,
            flatness: v[7].x as f32,
            spec_tint: v[8].x as f32,
            metallic: v[9].x as f32,
            clearcoat: v[10].x as f32,
            clearcoat_gloss: v[11].x as f32,
            eta: (v[12].x > 0.0).then_some(v[12].x as f32),
            specular: v[13].x as f32,
            diffuse_reflectance_sampling_rate: v[14].x as f32,
            main_specular_sampling_rate: v[15].x as f32,
            clearcoat_sampling_rate: v[16].x as f32,
        })
    }
}

impl super::BsdfModel for Principled {
    const NAME: &'static str = "principled";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            0 => self.params.base_color = v,
            1 => self.params.roughness = v.x,
            2 => self.params.anisotropic = v.x,
            4 => self.params.spec_trans = v.x,
            5 => self.params.sheen = v.x,
            6 => self.params.sheen_tint = v.x,
            7 => self.params.flatness = v.x,
            8 => self.params.spec_tint = v.x,
            9 => self.params.metallic = v.x,
            10 => self.params.clearcoat = v.x,
            11 => self.params.clearcoat_gloss = v.x,
            _ => {}
        }
    }

    /// The lobe weights, roughness and η depend on the parameters: made anew, as Mitsuba
    /// evaluates them at each shading point.
    fn params_set(&mut self) {
        *self = Principled::new(self.params);
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        Principled::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        Principled::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        Principled::sample(self, wi, u1, u2)
    }

    #[inline]
    fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        Principled::has_smooth_lobe(self, wi)
    }

    fn is_transmissive(&self) -> bool {
        Principled::is_transmissive(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;

    /// Index-matched (η = 1) the weight is (1 − |cos θ|)^5 from either side, down to grazing
    /// cosines where 1 − (1 − cos²θ) rounds to 0 in f32.
    #[test]
    fn schlick_weight_at_eta_one_is_exact_at_grazing_angles() {
        for c in [0.5f32, 1e-2, 1e-4, 1e-6] {
            let want = (1.0 - c).powi(5);
            for ci in [c, -c] {
                let w = schlick_weight_at(ci, 1.0);
                assert!((w - want).abs() <= 1e-6, "cos {ci}: {w} vs {want}");
            }
        }
    }

    /// A lobe of probability 0 is never picked, not even at u1 = 0 (which low-discrepancy
    /// samplers draw exactly): a fully metallic principled has no diffuse lobe, so u1 = 0
    /// samples the specular lobe, the same direction as u1 just above 0.
    #[test]
    fn a_lobe_of_probability_zero_is_not_picked_at_u1_zero() {
        let b = Principled::new(PrincipledParams {
            metallic: 1.0,
            roughness: 0.3,
            ..Default::default()
        });
        let wi = Vec3::new(0.3, 0.1, 0.9).normalize();
        let mut sampled = 0;
        for k in 0..64 {
            let u2 = Vec2::new((k % 8) as f32 / 8.0 + 0.06, (k / 8) as f32 / 8.0 + 0.06);
            let at_zero = b.sample(wi, 0.0, u2).map(|s| s.wo);
            assert_eq!(at_zero, b.sample(wi, 1e-6, u2).map(|s| s.wo), "u2 = {u2}");
            sampled += at_zero.is_some() as usize;
        }
        assert!(sampled > 32, "{sampled}");
    }

    #[test]
    fn principled_specular_maps_to_eta() {
        let p = PrincipledParams::default();
        assert!((p.relative_ior() - 1.5).abs() < 1e-6);
        // the normal-incidence reflectance is 0.08 specular
        for s in [0.1f32, 0.5, 0.9] {
            let eta = PrincipledParams { specular: s, ..p }.relative_ior();
            assert!((schlick_r0(eta) - 0.08 * s).abs() < 1e-6);
        }
        let with_trans = PrincipledParams {
            spec_trans: 0.5,
            ..p
        };
        assert_eq!(
            PrincipledParams {
                eta: Some(1.0),
                ..with_trans
            }
            .relative_ior(),
            1.001
        );
        assert_eq!(
            PrincipledParams {
                eta: Some(1.0),
                ..p
            }
            .relative_ior(),
            1.0
        );
        let tiny = PrincipledParams {
            specular: 0.0,
            ..with_trans
        }
        .relative_ior();
        assert!((schlick_r0(tiny) - 0.08e-3).abs() < 1e-7);
    }

    #[test]
    fn principled_gtr1_is_normalised_and_sampled() {
        for alpha in [0.1f32, 0.01] {
            let d = Gtr1 { alpha };
            // ∫ D cos θ dω = 1 on a fine grid in cos θ (D depends on θ only)
            let n = 200_000;
            let mut acc = 0.0f64;
            for i in 0..n {
                let c = (i as f64 + 0.5) / n as f64;
                let m = Vec3::new((1.0 - c * c).sqrt() as f32, 0.0, c as f32);
                acc += d.d(m) as f64 * c * 2.0 * std::f64::consts::PI / n as f64;
            }
            assert!((acc - 1.0).abs() < 2e-3, "{alpha}: {acc}");
            // the sampler's cos²θ CDF: P(cos²θ < x) matches ∫ D cos dω over that cap
            let mut s = SampleStream::new(5, 6, 7);
            let k = 200_000;
            let below = (0..k).filter(|_| d.sample(s.next_2d()).z < 0.99).count() as f64 / k as f64;
            let mut want = 0.0f64;
            for i in 0..n {
                let c = 0.99 * (i as f64 + 0.5) / n as f64;
                let m = Vec3::new((1.0 - c * c).sqrt() as f32, 0.0, c as f32);
                want += d.d(m) as f64 * c * 2.0 * std::f64::consts::PI * 0.99 / n as f64;
            }
            assert!((below - want).abs() < 5e-3, "{alpha}: {below} vs {want}");
        }
    }

    /// Random directions on the sphere, and the parameter sets of the tests.
    fn sphere(s: &mut SampleStream) -> Vec3 {
        crate::sampling::square_to_uniform_sphere(s.next_2d())
    }

    fn configurations() -> Vec<PrincipledParams> {
        let d = PrincipledParams::default();
        vec![
            d,
            PrincipledParams {
                base_color: crate::spectrum::rgb(0.9, 0.3, 0.1),
                roughness: 0.3,
                anisotropic: 0.7,
                metallic: 0.4,
                spec_trans: 0.5,
                spec_tint: 0.3,
                sheen: 0.6,
                sheen_tint: 0.5,
                flatness: 0.4,
                clearcoat: 0.8,
                clearcoat_gloss: 0.6,
                ..d
            },
            PrincipledParams {
                spec_trans: 1.0,
                eta: Some(1.33),
                roughness: 0.2,
                ..d
            },
            PrincipledParams {
                metallic: 1.0,
                roughness: 0.1,
                ..d
            },
        ]
    }

    #[test]
    fn principled_sample_weight_is_eval_over_pdf() {
        let mut s = SampleStream::new(1, 2, 3);
        for p in configurations() {
            let b = Principled::new(p);
            for _ in 0..2000 {
                let wi = sphere(&mut s);
                let Some(bs) = b.sample(wi, s.next_1d(), s.next_2d()) else {
                    continue;
                };
                let (f, pdf) = (b.eval(wi, bs.wo), b.pdf(wi, bs.wo));
                assert!(!bs.delta && pdf > 0.0);
                assert!((bs.pdf - pdf).abs() <= 1e-6 * pdf, "{p:?}: {bs:?} vs {pdf}");
                let w = f / pdf;
                assert!(
                    (bs.weight - w).abs().max_element() <= 1e-5 * w.max_element(),
                    "{p:?}: {bs:?} vs {w}"
                );
                if bs.wo.z * wi.z < 0.0 {
                    let want = if wi.z > 0.0 { b.eta } else { 1.0 / b.eta };
                    assert!((bs.eta - want).abs() < 1e-6);
                } else {
                    assert_eq!(bs.eta, 1.0);
                }
            }
        }
    }

    #[test]
    fn principled_pdf_covers_eval() {
        // Every direction the BSDF scatters into can be sampled.
        let mut s = SampleStream::new(4, 5, 6);
        for p in configurations() {
            let b = Principled::new(p);
            for _ in 0..20_000 {
                let (wi, wo) = (sphere(&mut s), sphere(&mut s));
                if b.eval(wi, wo).max_element() > 0.0 {
                    assert!(b.pdf(wi, wo) > 0.0, "{p:?}: {wi} {wo}");
                }
            }
        }
    }

    #[test]
    fn principled_is_black_from_behind_without_transmission() {
        let b = Principled::new(PrincipledParams {
            clearcoat: 1.0,
            sheen: 1.0,
            ..Default::default()
        });
        let wi = Vec3::new(0.3, 0.1, -0.9).normalize();
        assert!(!b.has_smooth_lobe(wi) && !b.is_transmissive());
        assert!(b.sample(wi, 0.5, Vec2::splat(0.5)).is_none());
        let wo = Vec3::new(-0.3, 0.0, -0.95).normalize();
        assert_eq!((b.eval(wi, wo), b.pdf(wi, wo)), (Spectrum::ZERO, 0.0));
    }
}
