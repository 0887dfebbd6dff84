//! Mitsuba's `twosided` adapter: a one-sided BSDF seen from either side. When `wi` lies
//! below the surface, both directions are mirrored through the tangent plane and the back
//! BSDF (the same as the front unless two were given) is used.

use super::{Bsdf, BsdfSample, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct TwoSided {
    pub front: Box<Bsdf>,
    pub back: Box<Bsdf>,
}

fn flip(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

impl TwoSided {
    /// Whether the side `wi` lies on has a smooth lobe (the back BSDF sees `wi` mirrored).
    pub(super) fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        if wi.z < 0.0 {
            self.back.has_smooth_lobe(flip(wi))
        } else {
            self.front.has_smooth_lobe(wi)
        }
    }

    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        if wi.z < 0.0 {
            self.back.eval(flip(wi), flip(wo))
        } else {
            self.front.eval(wi, wo)
        }
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z < 0.0 {
            self.back.pdf(flip(wi), flip(wo))
        } else {
            self.front.pdf(wi, wo)
        }
    }

    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z < 0.0 {
            let mut s = self.back.sample(flip(wi), u1, u2)?;
            s.wo = flip(s.wo);
            Some(s)
        } else {
            self.front.sample(wi, u1, u2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::Diffuse;
    use super::*;

    #[test]
    fn diffuse_is_one_sided_and_twosided_mirrors_it() {
        let d = Bsdf::Diffuse(Diffuse {
            reflectance: Vec3::new(0.5, 0.25, 1.0),
        });
        let wi = Vec3::new(0.0, 0.6, 0.8);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let f = d.eval(wi, wo);
        assert!((f - Vec3::new(0.5, 0.25, 1.0) * 0.8 / std::f32::consts::PI).length() < 1e-7);
        assert_eq!(d.eval(flip(wi), flip(wo)), Vec3::ZERO);
        assert!(d.sample(flip(wi), 0.5, Vec2::splat(0.3)).is_none());
        let back = Bsdf::Diffuse(Diffuse {
            reflectance: Vec3::ONE,
        });
        let t = Bsdf::TwoSided(TwoSided {
            front: Box::new(d.clone()),
            back: Box::new(back),
        });
        assert_eq!(t.eval(wi, wo), f);
        assert!(
            (t.eval(flip(wi), flip(wo)) - Vec3::splat(0.8 / std::f32::consts::PI)).length() < 1e-7
        );
        let s = t.sample(flip(wi), 0.5, Vec2::new(0.3, 0.7)).unwrap();
        assert!(s.wo.z < 0.0);
        assert!((t.pdf(flip(wi), s.wo) - s.pdf).abs() < 1e-6);
        // sample weight equals eval / pdf
        let w = t.eval(flip(wi), s.wo) / s.pdf;
        assert!((w - s.weight).length() < 1e-5);
    }
}
