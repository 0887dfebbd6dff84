//! Mitsuba's `blendbsdf`: a linear blend of two BSDFs.
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `weight` | texture (one value, clamped to [0, 1]) | required |
//! | nested `<bsdf>` × 2 | the first and the second BSDF | required |
//!
//! f = (1 − w) f₀ + w f₁, pdf = (1 − w) p₀ + w p₁. Sampling picks the second BSDF with
//! probability w (the first when u > w, as Mitsuba), samples it, and weights the direction by
//! the whole blend: weight = f(wo) / pdf(wo) with both BSDFs evaluated (one-sample MIS over the
//! two, as Mitsuba 3.9.1 does). A delta direction from one BSDF keeps its own weight and the
//! pdf times its selection probability (the other BSDF cannot produce it).
//!
//! ```xml
//! <bsdf type="blendbsdf">
//!     <float name="weight" value="0.3"/>
//!     <bsdf type="diffuse"/> <bsdf type="roughconductor"/>
//! </bsdf>
//! ```

use super::ShadingBsdf;
use crate::bsdf::{BsdfSample, Spectrum};
use glam::{Vec2, Vec3};

pub(super) fn eval(s: &ShadingBsdf, w: f32, nested: [u8; 2], wi: Vec3, wo: Vec3) -> Spectrum {
    s.eval_node(nested[0], wi, wo) * (1.0 - w) + s.eval_node(nested[1], wi, wo) * w
}

pub(super) fn pdf(s: &ShadingBsdf, w: f32, nested: [u8; 2], wi: Vec3, wo: Vec3) -> f32 {
    s.pdf_node(nested[0], wi, wo) * (1.0 - w) + s.pdf_node(nested[1], wi, wo) * w
}

pub(super) fn sample(
    s: &ShadingBsdf,
    w: f32,
    nested: [u8; 2],
    wi: Vec3,
    u1: f32,
    u2: Vec2,
) -> Option<BsdfSample> {
    // The chosen BSDF, its selection probability, and the rescaled u1.
    let (chosen, other, p_chosen, u) = if u1 > w {
        (nested[0], nested[1], 1.0 - w, (u1 - w) / (1.0 - w))
    } else {
        (nested[1], nested[0], w, u1 / w)
    };
    let mut bs = s.sample_node(chosen, wi, u.min(1.0 - f32::EPSILON / 2.0), u2)?;
    if bs.delta {
        bs.pdf *= p_chosen;
        return Some(bs);
    }
    let f_other = s.eval_node(other, wi, bs.wo);
    let pdf_other = s.pdf_node(other, wi, bs.wo);
    let pdf = p_chosen * bs.pdf + (1.0 - p_chosen) * pdf_other;
    if pdf.is_nan() || pdf <= 0.0 {
        return None;
    }
    let f = bs.weight * (bs.pdf * p_chosen) + f_other * (1.0 - p_chosen);
    bs.weight = f / pdf;
    bs.pdf = pdf;
    bs.weight.is_finite().then_some(bs)
}
