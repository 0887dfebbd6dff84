//! Mitsuba's `twosided`: one-sided BSDFs made visible from both sides.
//!
//! | parameter | type | default |
//! |---|---|---|
//! | nested `<bsdf>` | one or two BSDFs | required: the front; the back defaults to the front |
//!
//! When `wi` lies below the surface (cos θi < 0) both directions are mirrored through the
//! tangent plane and the back BSDF is used; otherwise the front one. (Mitsuba's
//! `allow_transmission` is not supported: the scene parser refuses it.)
//!
//! ```xml
//! <bsdf type="twosided"> <bsdf type="diffuse"/> </bsdf>
//! ```

use super::ShadingBsdf;
use crate::bsdf::{BsdfSample, Spectrum};
use glam::{Vec2, Vec3};

/// The mirror image of `v` through the tangent plane.
#[inline]
pub fn flip(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

pub(super) fn eval(s: &ShadingBsdf, front: u8, back: u8, wi: Vec3, wo: Vec3) -> Spectrum {
    if wi.z < 0.0 {
        s.eval_node(back, flip(wi), flip(wo))
    } else {
        s.eval_node(front, wi, wo)
    }
}

pub(super) fn pdf(s: &ShadingBsdf, front: u8, back: u8, wi: Vec3, wo: Vec3) -> f32 {
    if wi.z < 0.0 {
        s.pdf_node(back, flip(wi), flip(wo))
    } else {
        s.pdf_node(front, wi, wo)
    }
}

pub(super) fn sample(
    s: &ShadingBsdf,
    front: u8,
    back: u8,
    wi: Vec3,
    u1: f32,
    u2: Vec2,
) -> Option<BsdfSample> {
    if wi.z < 0.0 {
        let mut bs = s.sample_node(back, flip(wi), u1, u2)?;
        bs.wo = flip(bs.wo);
        Some(bs)
    } else {
        s.sample_node(front, wi, u1, u2)
    }
}
