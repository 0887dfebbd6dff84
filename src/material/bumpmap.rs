//! Mitsuba's `bumpmap`: the nested BSDF in a shading frame tilted by the gradient of a
//! height map (Blinn 1978, "Simulation of Wrinkled Surfaces"), with the same shadowing term
//! and flipping rules as [`super::normalmap`].
//!
//! | parameter | type | default |
//! |---|---|---|
//! | (any name) | texture: the height field, looked up with `eval_1` | required |
//! | `scale` | float: gradient multiplier | 1 |
//! | nested `<bsdf>` | one BSDF | required |
//! | `flip_invalid_normals` | boolean | true |
//! | `use_shadowing_function` | boolean | true |
//!
//! With (g_u, g_v) = scale · ∇h(u, v), the displaced partials are
//! dp/du' = dp/du + n (g_u − n · dp/du) and dp/dv' likewise (n the shading normal), the
//! perturbed normal is their normalised cross product, turned to the side of the geometric
//! normal. Its frame's tangent is dp/du made orthogonal to it. Mitsuba 3.9.1 forms that
//! tangent from the world-space dp/du and the shading-frame normal (mixing the two spaces);
//! this is reproduced, and it only matters for anisotropic nested BSDFs.
//!
//! ```xml
//! <bsdf type="bumpmap">
//!     <texture type="bitmap"> <boolean name="raw" value="true"/>
//!         <string name="filename" value="height.png"/> </texture>
//!     <float name="scale" value="0.02"/>
//!     <bsdf type="diffuse"/>
//! </bsdf>
//! ```

use super::normalmap::Perturbation;
use super::shading::Node;
use super::ShadingContext;
use crate::texture::Texture;

/// The node of a `bumpmap` at a shading point.
pub(super) fn node(
    height: &Texture,
    scale: f32,
    ctx: &ShadingContext,
    flip_invalid_normals: bool,
    use_shadowing_function: bool,
    nested: u8,
) -> Node {
    let g = height.eval_1_grad(&ctx.tex) * scale;
    let n = ctx.frame.n;
    let dp_du = ctx.dp_du + n * (g.x - n.dot(ctx.dp_du));
    let dp_dv = ctx.dp_dv + n * (g.y - n.dot(ctx.dp_dv));
    let mut pn = dp_du.cross(dp_dv).normalize_or_zero();
    if ctx.ng.dot(pn) < 0.0 {
        pn = -pn;
    }
    if pn == glam::Vec3::ZERO {
        // Degenerate partials: keep the shading normal.
        pn = n;
    }
    Node::Perturb {
        perturbation: Perturbation {
            n: ctx.frame.to_local(pn),
            tangent: ctx.dp_du,
            flip_invalid_normals,
            use_shadowing_function,
        },
        nested,
    }
}
