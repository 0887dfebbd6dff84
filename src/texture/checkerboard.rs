//! Mitsuba's `checkerboard` texture: two textures alternating on the unit squares of the
//! (transformed) texture coordinates.
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `color0` | texture | 0.4 |
//! | `color1` | texture | 0.2 |
//! | `to_uv` | transform | identity |
//!
//! With (u, v) = `to_uv` · uv and the fractional parts f = (u − ⌊u⌋, v − ⌊v⌋), `eval` takes
//! `color0` where (f.u > ½) = (f.v > ½) and `color1` elsewhere. Mitsuba 3.9.1's `eval_1` swaps
//! the two colours (it takes `color0` where the comparisons differ); that is reproduced here,
//! since a scalar checkerboard (roughness, metallic, ...) must match Mitsuba's render.
//!
//! ```xml
//! <texture type="checkerboard" name="reflectance">
//!     <rgb name="color0" value="0.8"/> <rgb name="color1" value="0.1"/>
//!     <transform name="to_uv"> <scale x="5" y="5"/> </transform>
//! </texture>
//! ```

use super::{Texture, TextureContext, UvTransform};
use crate::spectrum::Spectrum;

#[derive(Clone, Debug)]
pub struct Checkerboard {
    pub color0: Texture,
    pub color1: Texture,
    pub to_uv: UvTransform,
}

impl Checkerboard {
    /// Whether the comparisons of both fractional parts with ½ agree.
    #[inline]
    fn same_half(&self, ctx: &TextureContext) -> bool {
        let uv = self.to_uv.apply(ctx.uv);
        let f = uv - uv.floor();
        (f.x > 0.5) == (f.y > 0.5)
    }

    #[inline]
    pub fn eval(&self, ctx: &TextureContext) -> Spectrum {
        if self.same_half(ctx) {
            self.color0.eval(ctx)
        } else {
            self.color1.eval(ctx)
        }
    }

    /// Mitsuba 3.9.1's `eval_1`, with the colours the other way round from `eval`.
    #[inline]
    pub fn eval_1(&self, ctx: &TextureContext) -> f32 {
        if self.same_half(ctx) {
            self.color1.eval_1(ctx)
        } else {
            self.color0.eval_1(ctx)
        }
    }

    pub fn mean(&self) -> f32 {
        0.5 * (self.color0.mean() + self.color1.mean())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DVec2, Vec2, Vec3};

    fn board() -> Checkerboard {
        Checkerboard {
            color0: Texture::constant(Vec3::splat(0.8)),
            color1: Texture::constant(Vec3::splat(0.1)),
            to_uv: UvTransform::from_mat3(DMat3::from_scale(DVec2::splat(5.0))),
        }
    }

    #[test]
    fn squares_alternate_and_eval_1_swaps_the_colours() {
        let b = board();
        let at = |u: f32, v: f32| b.eval(&TextureContext::at_uv(Vec2::new(u, v))).x;
        let at1 = |u: f32, v: f32| b.eval_1(&TextureContext::at_uv(Vec2::new(u, v)));
        // to_uv scales by 5: uv (0.05, 0.05) -> (0.25, 0.25), both halves low: color0.
        assert_eq!(at(0.05, 0.05), 0.8);
        assert_eq!(at(0.15, 0.05), 0.1);
        assert_eq!(at(0.15, 0.15), 0.8);
        assert_eq!(at(-0.05, 0.05), 0.1, "negative u: floor, not truncation");
        assert_eq!(at1(0.05, 0.05), 0.1);
        assert_eq!(at1(0.15, 0.05), 0.8);
        assert!((b.mean() - 0.45).abs() < 1e-6);
    }
}
