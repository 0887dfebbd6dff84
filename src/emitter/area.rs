//! Mitsuba's `area` emitter: constant radiance leaving one side of a shape, the side its
//! (shading) normal points to. Sampled by choosing a point uniformly by area on the shape and
//! converting the area density to solid angle, p_ω = p_A r² / |cos θ_light| (Veach 1997, eq. 8.10).

use super::DirectionSample;
use crate::bsdf::Spectrum;
use crate::shape::{Shape, SurfaceInteraction};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct AreaEmitter {
    /// Index of the shape this emitter is attached to.
    pub shape: u32,
    pub radiance: Spectrum,
}

impl AreaEmitter {
    /// Radiance leaving the surface at `si` in direction `w` (world, pointing away from the
    /// surface).
    #[inline]
    pub fn eval(&self, si: &SurfaceInteraction, w: Vec3) -> Spectrum {
        if si.frame.n.dot(w) > 0.0 {
            self.radiance
        } else {
            Spectrum::ZERO
        }
    }

    pub fn sample_direction(
        &self,
        p_ref: Vec3,
        u: Vec2,
        shapes: &[Shape],
    ) -> Option<DirectionSample> {
        let ps = shapes[self.shape as usize].geometry.sample_position(u)?;
        let v = ps.p - p_ref;
        let dist2 = v.length_squared();
        if dist2 == 0.0 || !dist2.is_finite() {
            return None;
        }
        let dist = dist2.sqrt();
        let d = v / dist;
        let cos_light = ps.n.dot(-d);
        if cos_light <= 0.0 {
            return None; // back side: emits nothing towards p_ref
        }
        let pdf = ps.pdf * dist2 / cos_light;
        (pdf.is_finite() && pdf > 0.0).then_some(DirectionSample {
            p: ps.p,
            p_error: ps.p_error,
            n: ps.n,
            d,
            dist,
            pdf,
            radiance: self.radiance,
        })
    }

    /// Solid-angle density with which `sample_direction` from `p_ref` yields the point of
    /// `si` (the same shape hit by a ray from `p_ref`).
    pub fn pdf_direction(&self, p_ref: Vec3, si: &SurfaceInteraction, shapes: &[Shape]) -> f32 {
        let area = shapes[self.shape as usize].geometry.area();
        if area <= 0.0 {
            return 0.0;
        }
        let v = si.p - p_ref;
        let dist2 = v.length_squared();
        let cos_light = si.frame.n.dot(-v).abs() / dist2.sqrt();
        if cos_light == 0.0 {
            return 0.0;
        }
        (dist2 / (area as f32 * cos_light)).min(f32::MAX)
    }
}
