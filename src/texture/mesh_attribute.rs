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
//! Spectral mode (Mitsuba's spectral variants): a three-channel attribute is looked up as the
//! coefficients of spectra ([`crate::spectral::srgb_model_eval`]), the three vertices'
//! spectra interpolated with the barycentrics (a face's own spectrum for a face attribute);
//! the mesh converted the colours of attributes named `*color*` into coefficients when it
//! was built ([`crate::shape::Mesh::upsample_color_attributes`]). Like Mitsuba, a
//! three-channel attribute of another name is taken as coefficients as it is.
//!
//! ```xml
//! <texture type="mesh_attribute" name="reflectance">
//!     <string name="name" value="vertex_color"/>
//! </texture>
//! ```

use super::TextureContext;
use crate::spectral::srgb_model_eval;
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct MeshAttributeTexture {
    /// The attribute's name, `vertex_*` or `face_*`.
    pub name: String,
    pub scale: f32,
    /// Spectral mode: three-channel attributes hold spectral coefficients.
    pub spectral: bool,
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

    /// The value at the shading point and its wavelengths: RGB mode's [`Self::eval`] as
    /// lanes, or in spectral mode the spectrum of a three-channel attribute (see the top).
    #[inline]
    pub fn eval_spectrum(&self, ctx: &TextureContext) -> Vec4 {
        if !self.spectral {
            return crate::spectrum::from_rgb(self.eval(ctx));
        }
        let Some(a) = ctx.mesh.and_then(|m| m.attribute(&self.name)) else {
            return Vec4::ZERO;
        };
        if a.channels != 3 {
            return crate::spectrum::from_rgb(self.eval(ctx));
        }
        let spectrum = |i: usize| srgb_model_eval(a.row(i).to_array(), ctx.wavelengths);
        let value = if a.per_face {
            spectrum(ctx.prim as usize)
        } else {
            let Some(&[i0, i1, i2]) = ctx.mesh.and_then(|m| m.triangles.get(ctx.prim as usize))
            else {
                return Vec4::ZERO;
            };
            let b = [1.0 - ctx.bary.x - ctx.bary.y, ctx.bary.x, ctx.bary.y];
            // fma(c0, b0, fma(c1, b1, c2 b2)), Mitsuba's order
            let fma = |a: Vec4, w: f32, c: Vec4| {
                Vec4::from_array(std::array::from_fn(|k| {
                    (a[k] as f64 * w as f64 + c[k] as f64) as f32
                }))
            };
            let inner = fma(spectrum(i1 as usize), b[1], spectrum(i2 as usize) * b[2]);
            fma(spectrum(i0 as usize), b[0], inner)
        };
        value * self.scale
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
