//! Mitsuba's `mask`: a BSDF that is only partly there (cut-out leaves, fences).
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `opacity` | texture (one value, clamped to [0, 1]) | 0.5 |
//! | nested `<bsdf>` | one BSDF | required |
//!
//! eval = opacity · nested, pdf = opacity · nested pdf. Sampling picks the nested BSDF with
//! probability `opacity` (its weight unchanged), else passes the light straight through (a
//! delta `null` event with weight 1, as Mitsuba's mask). Shadow rays are blocked by masked
//! surfaces, as in Mitsuba's path tracer, so light reaches through the holes by the pass-through
//! events only.
//!
//! ```xml
//! <bsdf type="mask">
//!     <texture name="opacity" type="bitmap"> <string name="filename" value="leaf.png"/> </texture>
//!     <bsdf type="diffuse"/>
//! </bsdf>
//! ```

use super::shading::null_sample;
use super::ShadingBsdf;
use crate::bsdf::{BsdfSample, Spectrum};
use glam::{Vec2, Vec3};

pub(super) fn eval(s: &ShadingBsdf, opacity: f32, nested: u8, wi: Vec3, wo: Vec3) -> Spectrum {
    s.eval_node(nested, wi, wo) * opacity
}

pub(super) fn pdf(s: &ShadingBsdf, opacity: f32, nested: u8, wi: Vec3, wo: Vec3) -> f32 {
    s.pdf_node(nested, wi, wo) * opacity
}

pub(super) fn sample(
    s: &ShadingBsdf,
    opacity: f32,
    nested: u8,
    wi: Vec3,
    u1: f32,
    u2: Vec2,
) -> Option<BsdfSample> {
    if u1 < opacity {
        let mut bs = s.sample_node(nested, wi, u1 / opacity, u2)?;
        bs.pdf *= opacity;
        Some(bs)
    } else {
        Some(null_sample(wi, 1.0 - opacity))
    }
}
