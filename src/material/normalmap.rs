//! Mitsuba's `normalmap`: the nested BSDF in a shading frame tilted by a tangent-space normal
//! map, with the shadowing term of Estevez et al. 2019 ("A Microfacet-Based Shadowing Function
//! to Solve the Bump Terminator Problem", Ray Tracing Gems ch. 12) against the dark
//! terminator that tilted normals cause.
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `normalmap` | texture (three raw values: n = 2 · value − 1, in the shading frame) | required |
//! | nested `<bsdf>` | one BSDF | required |
//! | `flip_invalid_normals` | boolean | true |
//! | `use_shadowing_function` | boolean | true |
//!
//! The perturbed frame (in the shading frame): n as read (mirrored to (−nx, −ny, nz) when it
//! faces away from `wi` and `flip_invalid_normals` is set), normalised; s the tangent
//! (1, 0, 0) made orthogonal to n; t = n × s. The nested BSDF sees wi and wo in that frame;
//! directions on different sides of the two frames give 0, and values are multiplied by the
//! shadowing term 2 / (1 + √(1 + α² tan² θo)) with α² = min(tan² θn / 8, 1). `bumpmap`
//! perturbs the frame the same way, from a height map's gradient (see [`super::bumpmap`]).
//!
//! ```xml
//! <bsdf type="normalmap">
//!     <texture name="normalmap" type="bitmap"> <boolean name="raw" value="true"/>
//!         <string name="filename" value="normals.png"/> </texture>
//!     <bsdf type="roughconductor"/>
//! </bsdf>
//! ```

use super::{ShadingBsdf, ShadingContext};
use crate::bsdf::{BsdfSample, Spectrum};
use crate::geometry::Frame;
use crate::material::shading::Node;
use crate::texture::Texture;
use glam::{Vec2, Vec3};

/// A tilted shading frame, relative to the shading frame: the raw normal (before the
/// per-`wi` flip) and the tangent that its frame's `s` is made from.
#[derive(Clone, Copy, Debug)]
pub struct Perturbation {
    pub n: Vec3,
    pub tangent: Vec3,
    pub flip_invalid_normals: bool,
    pub use_shadowing_function: bool,
}

/// Mitsuba's shadowing term for a perturbed normal `n` and a direction `wo`, both in the
/// unperturbed shading frame.
pub fn shadow_terminator(n: Vec3, wo: Vec3) -> f32 {
    let tan2 = |v: Vec3| {
        let c2 = v.z * v.z;
        ((1.0 - c2) / c2).max(0.0)
    };
    let alpha2 = (0.125 * tan2(n)).min(1.0);
    2.0 / (1.0 + (1.0 + alpha2 * tan2(wo)).sqrt())
}

impl Perturbation {
    /// The perturbed frame seen from `wi` (flipped if it faces away and flipping is on).
    #[inline]
    fn frame(&self, wi: Vec3) -> Frame {
        let mut n = self.n;
        if self.flip_invalid_normals && wi.z * wi.dot(n) <= 0.0 {
            n = Vec3::new(-n.x, -n.y, n.z);
        }
        let n = n.normalize_or_zero();
        let s = (self.tangent - n * n.dot(self.tangent)).normalize_or_zero();
        Frame {
            s,
            t: n.cross(s),
            n,
        }
    }

    #[inline]
    fn shadowing(&self, f: &Frame, wo: Vec3) -> f32 {
        if self.use_shadowing_function {
            shadow_terminator(f.n, wo)
        } else {
            1.0
        }
    }

    pub(super) fn eval(&self, s: &ShadingBsdf, nested: u8, wi: Vec3, wo: Vec3) -> Spectrum {
        let f = self.frame(wi);
        let wo_p = f.to_local(wo);
        if wo.z * wo_p.z <= 0.0 {
            return Spectrum::ZERO;
        }
        s.eval_node(nested, f.to_local(wi), wo_p) * self.shadowing(&f, wo)
    }

    pub(super) fn pdf(&self, s: &ShadingBsdf, nested: u8, wi: Vec3, wo: Vec3) -> f32 {
        let f = self.frame(wi);
        let wo_p = f.to_local(wo);
        if wo.z * wo_p.z <= 0.0 {
            return 0.0;
        }
        s.pdf_node(nested, f.to_local(wi), wo_p)
    }

    pub(super) fn sample(
        &self,
        s: &ShadingBsdf,
        nested: u8,
        wi: Vec3,
        u1: f32,
        u2: Vec2,
    ) -> Option<BsdfSample> {
        let f = self.frame(wi);
        let mut bs = s.sample_node(nested, f.to_local(wi), u1, u2)?;
        let wo = f.to_world(bs.wo);
        if bs.wo.z * wo.z <= 0.0 {
            return None;
        }
        bs.wo = wo;
        bs.weight *= self.shadowing(&f, wo);
        Some(bs)
    }
}

/// The node of a `normalmap` at a shading point: n = 2 · eval_3 − 1.
pub(super) fn node(
    map: &Texture,
    ctx: &ShadingContext,
    flip_invalid_normals: bool,
    use_shadowing_function: bool,
    nested: u8,
) -> Node {
    let n = map.eval_3(&ctx.tex) * 2.0 - Vec3::ONE;
    Node::Perturb {
        perturbation: Perturbation {
            n,
            tangent: Vec3::X,
            flip_invalid_normals,
            use_shadowing_function,
        },
        nested,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shadowing_is_one_for_unperturbed_normals_and_at_normal_incidence() {
        assert_eq!(shadow_terminator(Vec3::Z, Vec3::new(0.6, 0.0, 0.8)), 1.0);
        let n = Vec3::new(0.3, 0.0, 0.954).normalize();
        assert!((shadow_terminator(n, Vec3::Z) - 1.0).abs() < 1e-6);
        // Grazing directions under a tilted normal are shadowed.
        let g = shadow_terminator(n, Vec3::new(0.999, 0.0, 0.04).normalize());
        assert!(g < 0.9 && g > 0.0, "{g}");
    }
}
