//! Textures: values that vary over a surface, looked up once per shading point and handed to
//! the BSDFs as plain values (pbrt-v4's texture evaluation before `GetBxDF`; Mitsuba's
//! `Texture::eval`, `eval_1`, `eval_3`, `mean`). A closed set, dispatched by `match`:
//!
//! | plugin | parameters (Mitsuba 3.9.1) | here |
//! |---|---|---|
//! | constant colours: `<rgb>`, `<float>`, `<spectrum>`, `rawconstant` | `value` | [`Texture::Constant`] |
//! | `bitmap` | `filename`, `raw`, `filter_type`, `wrap_mode`, `to_uv` | [`bitmap::BitmapTexture`] |
//! | `checkerboard` | `color0` (0.4), `color1` (0.2), `to_uv` | [`checkerboard::Checkerboard`] |
//! | `mesh_attribute` | `name` (`vertex_*`, `face_*`), `scale` (1) | [`mesh_attribute::MeshAttributeTexture`] |
//! | `volume` | `volume` (a `constvolume` or `gridvolume`, looked up at the point) | [`volume::VolumeTexture`] |
//!
//! Mitsuba's three lookups: `eval` is the colour (linear RGB), `eval_1` one value (the mean
//! of a constant colour, a bitmap's own rule, the single channel of an attribute) for
//! roughness, opacity, weights and heights, `eval_3` the raw three values (normal maps).
//! Adding a texture: a file here with its struct, a variant of [`Texture`] and its arm in each
//! method, a `TextureDesc` variant in `scene::description` and its arm in `scene::build`.

pub mod bitmap;
pub mod checkerboard;
pub mod color;
pub mod mesh_attribute;
pub mod volume;

pub use bitmap::BitmapTexture;
pub use checkerboard::Checkerboard;
pub use color::ColorValue;
pub use mesh_attribute::MeshAttributeTexture;
pub use volume::VolumeTexture;

use crate::shape::Mesh;
use crate::spectrum::{from_rgb, to_rgb, Spectrum};
use glam::{DMat3, Vec2, Vec3};

/// What a texture lookup needs of the shading point: the surface coordinates, the position
/// (volume textures), and for mesh attributes the triangle, its barycentrics and the mesh.
#[derive(Clone, Copy, Debug)]
pub struct TextureContext<'a> {
    pub uv: Vec2,
    /// The point, in the space the scene is built in (world space shifted to the camera).
    pub p: Vec3,
    /// Triangle index within the mesh (0 for analytic shapes).
    pub prim: u32,
    /// Barycentrics (b1, b2) of the hit in its triangle (meshes only).
    pub bary: Vec2,
    /// The mesh hit, if it is one.
    pub mesh: Option<&'a Mesh>,
    /// The path's four wavelengths (nm) in spectral mode (ignored in RGB mode).
    pub wavelengths: glam::Vec4,
}

impl TextureContext<'_> {
    /// A context at surface coordinates `uv` with no mesh and wavelengths `wavelengths`
    /// (spectral mode; ignored in RGB mode).
    pub fn at_uv_wl(uv: Vec2, wavelengths: glam::Vec4) -> Self {
        TextureContext {
            wavelengths,
            ..TextureContext::at_uv(uv)
        }
    }

    /// A context at surface coordinates `uv` with no mesh (for tests and constant lookups).
    pub fn at_uv(uv: Vec2) -> Self {
        TextureContext {
            uv,
            p: Vec3::ZERO,
            prim: 0,
            bary: Vec2::ZERO,
            mesh: None,
            wavelengths: glam::Vec4::ZERO,
        }
    }
}

/// How a texture is looked up (Mitsuba's `eval`, `eval_1`, `eval_3`), for the checks of
/// spectral mode ([`Texture::spectral_refusal`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookup {
    /// `eval`: a colour, a spectrum in spectral mode.
    Spectrum,
    /// `eval_1` (and `eval_1_grad`): one value.
    One,
    /// `eval_3`: three raw values (normal maps).
    Three,
}

/// A texture, ready to be looked up.
#[derive(Clone, Debug)]
pub enum Texture {
    /// The same value everywhere: `rgb` for `eval`, `scalar` for `eval_1` (Mitsuba: the value
    /// of a `<float>`, the mean of an `<rgb>`), `raw` for `eval_3` (a `rawconstant`'s vector;
    /// otherwise `rgb`).
    Constant {
        rgb: Vec3,
        scalar: f32,
    },
    /// Spectral mode's constant: a spectrum evaluated at the path's wavelengths, `scalar` for
    /// `eval_1` (Mitsuba's `mean()` of the spectrum), `rgb` for `eval_3` (Mitsuba's `srgb`
    /// keeps its colour there).
    Spectral {
        value: Box<ColorValue>,
        scalar: f32,
        rgb: Vec3,
    },
    Bitmap(BitmapTexture),
    Checkerboard(Box<Checkerboard>),
    MeshAttribute(MeshAttributeTexture),
    Volume(VolumeTexture),
}

impl Texture {
    /// A constant colour (Mitsuba's `srgb` texture: `eval_1` is the mean of the channels).
    pub fn constant(rgb: Vec3) -> Self {
        Texture::Constant {
            rgb,
            scalar: (rgb.x + rgb.y + rgb.z) / 3.0,
        }
    }

    /// The colour at the shading point (linear RGB).
    #[inline]
    pub fn eval(&self, ctx: &TextureContext) -> Spectrum {
        match self {
            Texture::Constant { rgb, .. } => from_rgb(*rgb),
            Texture::Spectral { value, .. } => value.eval(ctx.wavelengths),
            Texture::Bitmap(b) => b.eval_spectrum(ctx.uv, ctx.wavelengths),
            Texture::Checkerboard(c) => c.eval(ctx),
            Texture::MeshAttribute(a) => a.eval_spectrum(ctx),
            Texture::Volume(v) => v.eval_spectrum(ctx.p, ctx.wavelengths),
        }
    }

    /// One value at the shading point (Mitsuba's `eval_1`).
    #[inline]
    pub fn eval_1(&self, ctx: &TextureContext) -> f32 {
        match self {
            Texture::Constant { scalar, .. } | Texture::Spectral { scalar, .. } => *scalar,
            Texture::Bitmap(b) => b.eval_1(ctx.uv),
            Texture::Checkerboard(c) => c.eval_1(ctx),
            Texture::MeshAttribute(a) => a.eval_1(ctx),
            Texture::Volume(v) => v.eval_1(ctx.p),
        }
    }

    /// The raw three values at the shading point (Mitsuba's `eval_3`; normal maps).
    #[inline]
    pub fn eval_3(&self, ctx: &TextureContext) -> Vec3 {
        match self {
            Texture::Constant { rgb, .. } | Texture::Spectral { rgb, .. } => *rgb,
            Texture::Bitmap(b) => b.eval(ctx.uv),
            Texture::Checkerboard(c) => to_rgb(c.eval(ctx)),
            Texture::MeshAttribute(a) => a.eval(ctx),
            Texture::Volume(v) => v.eval(ctx.p),
        }
    }

    /// The gradient of `eval_1` with respect to (u, v) (Mitsuba's `eval_1_grad`, for bump
    /// maps): a bitmap's bilinear slope; zero for constants, and zero almost everywhere for
    /// a checkerboard or a face attribute (piecewise constant).
    #[inline]
    pub fn eval_1_grad(&self, ctx: &TextureContext) -> Vec2 {
        match self {
            Texture::Bitmap(b) => b.eval_1_grad(ctx.uv),
            // Mitsuba's volume texture has no uv gradient either.
            Texture::Constant { .. }
            | Texture::Spectral { .. }
            | Texture::Checkerboard(_)
            | Texture::MeshAttribute(_)
            | Texture::Volume(_) => Vec2::ZERO,
        }
    }

    /// The mean over the texture's domain (Mitsuba's `mean`).
    pub fn mean(&self) -> f32 {
        match self {
            Texture::Constant { scalar, .. } | Texture::Spectral { scalar, .. } => *scalar,
            Texture::Bitmap(b) => b.mean(),
            Texture::Checkerboard(c) => c.mean(),
            // Mitsuba has no mean for an attribute; its constant scale is what is known.
            Texture::MeshAttribute(a) => a.scale,
            Texture::Volume(v) => v.mean(),
        }
    }

    /// Spectral mode: why Mitsuba 3.9.1's spectral variants refuse to look this texture up as
    /// `lookup` (they throw at the first lookup; penumbra says so when the scene is built),
    /// or `None`. A three-channel bitmap converted into spectra (`raw` = false) answers
    /// spectral lookups only; a `raw` three-channel bitmap cannot be a spectrum.
    pub fn spectral_refusal(&self, lookup: Lookup) -> Option<String> {
        match self {
            Texture::Bitmap(b) if b.channels() == 3 => {
                match (b.holds_coefficients(), lookup) {
                    (true, Lookup::One | Lookup::Three) => Some(format!(
                        "a bitmap texture is looked up as {} here, but spectral mode converts a three-channel bitmap into spectra (Mitsuba refuses this lookup too): use a one-channel image, or raw=\"true\"",
                        if lookup == Lookup::One { "one value" } else { "raw RGB (a normal map)" }
                    )),
                    (false, Lookup::Spectrum) => Some(
                        "a bitmap texture has raw=\"true\" and three channels: spectral mode cannot look it up as a spectrum (Mitsuba refuses it too); drop raw=\"true\"".into()
                    ),
                    _ => None,
                }
            }
            Texture::Checkerboard(c) => c
                .color0
                .spectral_refusal(lookup)
                .or_else(|| c.color1.spectral_refusal(lookup)),
            Texture::Volume(v) => v.spectral_refusal(lookup),
            _ => None,
        }
    }

    /// Whether the texture varies over the surface (Mitsuba's `is_spatially_varying`): not
    /// for constants, nor for spectral mode's constants (which vary with wavelength only).
    pub fn is_spatially_varying(&self) -> bool {
        !matches!(self, Texture::Constant { .. } | Texture::Spectral { .. })
    }

    /// Whether the texture is one value everywhere (then a BSDF using only such textures can
    /// be built once).
    pub fn is_constant(&self) -> bool {
        matches!(self, Texture::Constant { .. })
    }

    /// A point of the texture's [0, 1]² drawn in proportion to its values, and its density
    /// (Mitsuba's `sample_position`: textured emitters). Only bitmaps prepared with
    /// [`BitmapTexture::prepare_sampling`] do better than uniform.
    pub fn sample_position(&self, u: Vec2) -> (Vec2, f32) {
        match self {
            Texture::Bitmap(b) => b.sample_position(u),
            _ => (u, 1.0),
        }
    }

    /// The density of [`Texture::sample_position`] at `uv`.
    pub fn pdf_position(&self, uv: Vec2) -> f32 {
        match self {
            Texture::Bitmap(b) => b.pdf_position(uv),
            _ => 1.0,
        }
    }
}

/// A 2D affine map of texture coordinates (Mitsuba's `to_uv`, a 3x3 matrix acting on
/// (u, v, 1)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    m: [f32; 6],
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform {
        m: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    };

    /// From a 3x3 homogeneous 2D matrix (the last row is assumed to be 0 0 1).
    pub fn from_mat3(m: DMat3) -> Self {
        UvTransform {
            m: [
                m.x_axis.x as f32,
                m.y_axis.x as f32,
                m.z_axis.x as f32,
                m.x_axis.y as f32,
                m.y_axis.y as f32,
                m.z_axis.y as f32,
            ],
        }
    }

    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let m = &self.m;
        Vec2::new(
            m[0] * uv.x + m[1] * uv.y + m[2],
            m[3] * uv.x + m[4] * uv.y + m[5],
        )
    }
}
