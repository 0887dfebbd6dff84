//! Mitsuba's `mesh_attribute` texture: a per-vertex or per-face attribute of the mesh hit
//! (PLY properties such as `vertex_color` or `face_color`), times `scale`.
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `name` | string: `vertex_<name>` or `face_<name>` | required |
//! | `scale` | float | 1 |
//!
//! A vertex attribute is interpolated with the hit's barycentrics, a face attribute is the
//! hit triangle's. `eval` of a one-channel attribute is that value in every channel, of a
//! three-channel one its RGB; `eval_1` needs a one-channel attribute (Mitsuba throws
//! otherwise; here it is the mean of the channels). A shape without the attribute, or that is
//! not a mesh, gives 0 (Mitsuba throws on a mesh without it; the scene builder checks that
//! every mesh using the texture has it).
//!
//! ```xml
//! <texture type="mesh_attribute" name="reflectance">
//!     <string name="name" value="vertex_color"/>
//! </texture>
//! ```

use super::TextureContext;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct MeshAttributeTexture {
    /// The attribute's name, `vertex_*` or `face_*`.
    pub name: String,
    pub scale: f32,
}

impl MeshAttributeTexture {
    /// The attribute's value at the shading point, as many channels as it has (1 or 3).
    #[inline]
    fn value(&self, ctx: &TextureContext) -> Option<(Vec3, usize)> {
        let mesh = ctx.mesh?;
        mesh.eval_attribute(&self.name, ctx.prim as usize, ctx.bary)
    }

    #[inline]
    pub fn eval(&self, ctx: &TextureContext) -> Vec3 {
        match self.value(ctx) {
            Some((v, 1)) => Vec3::splat(v.x) * self.scale,
            Some((v, _)) => v * self.scale,
            None => Vec3::ZERO,
        }
    }

    #[inline]
    pub fn eval_1(&self, ctx: &TextureContext) -> f32 {
        match self.value(ctx) {
            Some((v, 1)) => v.x * self.scale,
            Some((v, _)) => (v.x + v.y + v.z) / 3.0 * self.scale,
            None => 0.0,
        }
    }
}
