//! Mitsuba's `bitmap` texture (src/textures/bitmap.cpp of Mitsuba 3.9.1): an image looked
//! up at a surface's uv, with bilinear or nearest filtering and repeat, mirror or clamp
//! wrapping, in the RGB variants.
//!
//! | Parameter | Type | Default | Notes |
//! | --- | --- | --- | --- |
//! | `filename` | string | — | PNG, JPEG, BMP or OpenEXR ([`crate::io::image`]) |
//! | `raw` | bool | false | keep 8/16-bit values as stored (v/255, v/65535) instead of decoding sRGB: normal maps, roughness maps |
//! | `filter_type` | string | `bilinear` | or `nearest` |
//! | `wrap_mode` | string | `repeat` | or `mirror`, `clamp` |
//! | `to_uv` | transform | identity | 2D affine applied to uv before the lookup |
//! | `format` | string | `auto` | storage precision, [`Format`] |
//! | `accel` | bool | true | CUDA hardware interpolation only: accepted and ignored (penumbra is CPU-only and exact) |
//!
//! ```xml
//! <texture type="bitmap">
//!     <string name="filename" value="texture.png"/>
//!     <string name="wrap_mode" value="mirror"/>
//! </texture>
//! ```
//!
//! Conventions, each checked against Mitsuba's own lookups
//! (validation/mitsuba/bitmap_lookups.py → tests/data/mitsuba_bitmap_lookups.txt):
//!
//! - **Orientation.** Row 0 of the texture is the first row of the file (the top of the
//!   picture), at v = 0: the texture itself does not flip v. (Mitsuba's mesh loaders flip the
//!   files' v instead, so that a mesh's v = 1 is the top; that is the mesh code's business.)
//! - **Texel centres** are at ((i + ½)/W, (j + ½)/H).
//! - **Bilinear:** x = u·W − ½ (one fused multiply-add in f32, as Dr.Jit's FMA build does),
//!   i = ⌊x⌋, w₁ = x − i, w₀ = 1 − w₁, likewise in y; the four texels (i, j), (i+1, j),
//!   (i, j+1), (i+1, j+1) are each wrapped on their own and accumulated in that order
//!   with fused multiply-adds, weight w_x·w_y.
//! - **Nearest:** texel (⌊u·W⌋, ⌊v·H⌋), wrapped: a texel owns [i/W, (i+1)/W).
//! - **Wrap** (per integer texel index, resolution n): `repeat` i mod n (Euclidean);
//!   `mirror` reflects with the edge texel repeated (… 1 0 | 0 1 … n−1 | n−1 n−2 …), i.e.
//!   m = i mod 2n, m < n ? m : 2n−1−m; `clamp` clamps to [0, n−1].
//! - **`to_uv`:** uv' = M·(u, v, 1) with a 2D affine M stored in f32 (u' = m00 u + m01 v + m02
//!   as fma(m01, v, fma(m00, u, m02))). From Mitsuba's 4x4 `<transform>` it keeps entries
//!   (0,0), (0,1), (0,3), (1,0), (1,1), (1,3) (the z row and column and the projective row are
//!   dropped): [`to_uv_from_4x4`].
//! - **Channels** ([`crate::io::image`]): grey and grey+alpha images give one channel, RGB
//!   and RGBA three; alpha is dropped (not premultiplied), XYZ converted to RGB.
//!   `eval` returns RGB (a grey value replicated), `eval_1` the grey value or the luminance
//!   0.212671 R + 0.715160 G + 0.072169 B of the interpolated RGB, and `mean` the mean over
//!   all texels of the grey value or of the luminance: a single number (Mitsuba's
//!   `Texture::mean()` is a `Float`; the plastic BSDFs use it for their sampling weights).
//!   penumbra sums in f64; Mitsuba's scalar variants sum in f32, which is off by 0.3% on a
//!   2048² PNG and 1.3% on a 2048² JPEG of the suite (only sampling weights depend on it).
//! - **sRGB.** Integer images (PNG, JPEG, BMP) are sRGB-encoded unless `raw`; EXR data is
//!   linear. The decode is the exact IEC 61966-2-1 curve (Mitsuba uses a rational fit of it,
//!   within 4e-7). Where it happens depends on the storage, see [`Format`]; with the default
//!   storage of 8-bit data each of the four texels is decoded before interpolating.
//! - **Sub-2x2 images.** Mitsuba pads them to 2x2 by repeating the last row/column; that
//!   changes no lookup and no mean, so penumbra keeps them as they are.

use crate::io::image::{self, Image, Samples};
use crate::sampling::Distribution2D;
use glam::{DMat3, DMat4, Vec2, Vec3};
use half::f16;
use std::path::Path;
use std::sync::Arc;

/// `filter_type`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Filter {
    #[default]
    Bilinear,
    Nearest,
}

impl Filter {
    /// From Mitsuba's name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "bilinear" => Ok(Filter::Bilinear),
            "nearest" => Ok(Filter::Nearest),
            _ => Err(format!(
                "invalid filter type \"{name}\", must be one of: \"nearest\", or \"bilinear\""
            )),
        }
    }
}

/// `wrap_mode`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Wrap {
    #[default]
    Repeat,
    Mirror,
    Clamp,
}

impl Wrap {
    /// From Mitsuba's name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "repeat" => Ok(Wrap::Repeat),
            "mirror" => Ok(Wrap::Mirror),
            "clamp" => Ok(Wrap::Clamp),
            _ => Err(format!(
                "invalid wrap mode \"{name}\", must be one of: \"repeat\", \"mirror\", or \"clamp\""
            )),
        }
    }

    /// The texel index for integer position `i` along an axis of `n` texels.
    #[inline]
    pub fn apply(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        let r = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::Clamp => i.clamp(0, n - 1),
            Wrap::Mirror => {
                let m = i.rem_euclid(2 * n);
                if m < n {
                    m
                } else {
                    2 * n - 1 - m
                }
            }
        };
        r as usize
    }
}

/// `format`: how texels are stored, which fixes where the sRGB decode happens.
///
/// - `auto` (default): 8-bit data as 8-bit ([`Format::UInt8`]); 16-bit data (PNG) and half
///   data (EXR) as half ([`Format::Float16`]); float data as float ([`Format::Variant`]).
/// - `variant`: f32, decoded to linear at load.
/// - `float16` (or `fp16`): half, decoded to linear at load (in f32, then rounded).
/// - `uint8`: 8 bits per channel, decoded on each texel fetch through a 256-entry table.
///   16-bit data is requantised (sRGB-encoded, unless `raw`) and float data clamped to
///   [0, 1] and quantised linearly, both rounding to nearest: Mitsuba dithers there, so such
///   textures agree with Mitsuba only to one code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Format {
    #[default]
    Auto,
    Variant,
    Float16,
    UInt8,
}

impl Format {
    /// From Mitsuba's name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "auto" => Ok(Format::Auto),
            "variant" => Ok(Format::Variant),
            "float16" | "fp16" => Ok(Format::Float16),
            "uint8" => Ok(Format::UInt8),
            _ => Err(format!(
                "invalid format \"{name}\", must be one of: \"auto\", \"variant\", \"float16\", or \"uint8\""
            )),
        }
    }
}

use crate::spectral;
use crate::spectrum::srgb_to_linear;

#[derive(Clone, Debug)]
enum Texels {
    /// Stored codes and their values (Mitsuba normalises with `v * (1.f / 255.f)`, then
    /// decodes sRGB unless raw).
    U8 {
        data: Vec<u8>,
        lut: Box<[f32; 256]>,
    },
    F16(Vec<f16>),
    F32(Vec<f32>),
}

/// The image data of a bitmap texture, as stored for lookups (share it with an `Arc`: a
/// scene's cache can key it by path and `raw`).
#[derive(Clone, Debug)]
pub struct TexImage {
    width: usize,
    height: usize,
    channels: usize,
    texels: Texels,
    /// Mean luminance (or grey value) over the texels; with `coefficients`, the mean of
    /// their spectra (`srgb_model_mean`).
    mean: f32,
    mean_rgb: Vec3,
    /// Spectral mode: the three channels of each texel hold the sigmoid-polynomial
    /// coefficients of its colour (`srgb_model_fetch`), not the colour.
    coefficients: bool,
}

impl TexImage {
    /// Loads an image file with the default storage (`format` = `auto`).
    pub fn load(path: &Path, raw: bool) -> Result<Self, String> {
        Self::load_with_format(path, raw, Format::Auto)
    }

    /// Loads an image file with the given storage.
    pub fn load_with_format(path: &Path, raw: bool, format: Format) -> Result<Self, String> {
        Ok(Self::from_image(image::read(path)?, raw, format))
    }

    /// Decodes an image held in memory (tests, the fuzz target).
    pub fn from_bytes(bytes: &[u8], raw: bool, format: Format) -> Result<Self, String> {
        Ok(Self::from_image(image::decode(bytes)?, raw, format))
    }

    /// Builds the texture data from a decoded image. Panics unless it has 1 or 3 channels, at
    /// least one texel and `width * height * channels` samples, as [`image::decode`] ensures.
    pub fn from_image(image: Image, raw: bool, format: Format) -> Self {
        let Image {
            width,
            height,
            channels,
            samples,
            ..
        } = image;
        assert!(channels == 1 || channels == 3, "1 or 3 channels");
        assert!(width > 0 && height > 0, "at least one texel");
        assert_eq!(samples.len(), width * height * channels);
        let srgb = samples.is_integer() && !raw;
        let storage = match format {
            Format::Auto => match samples {
                Samples::U8(_) => Format::UInt8,
                Samples::U16(_) | Samples::F16(_) => Format::Float16,
                Samples::F32(_) => Format::Variant,
            },
            f => f,
        };
        // the linear value of sample i, in f64
        let linear = |s: &Samples, i: usize| -> f64 {
            let v = match s {
                Samples::U8(d) => d[i] as f64 / 255.0,
                Samples::U16(d) => d[i] as f64 / 65535.0,
                Samples::F16(d) => d[i].to_f64(),
                Samples::F32(d) => d[i] as f64,
            };
            if srgb {
                srgb_to_linear(v)
            } else {
                v
            }
        };
        let texels = match storage {
            Format::UInt8 => {
                let lut: Box<[f32; 256]> = Box::new(std::array::from_fn(|i| {
                    let v = i as f32 * (1.0f32 / 255.0);
                    if srgb {
                        srgb_to_linear(v as f64) as f32
                    } else {
                        v
                    }
                }));
                let quantise = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                let data = match samples {
                    Samples::U8(d) => d,
                    // stays sRGB-encoded when srgb (the table decodes it), else linear
                    Samples::U16(d) => d.iter().map(|&v| quantise(v as f64 / 65535.0)).collect(),
                    // float data is linear (NaN quantises to 0)
                    ref s => (0..s.len())
                        .map(|i| {
                            let v = linear(s, i);
                            if v.is_nan() {
                                0
                            } else {
                                quantise(v)
                            }
                        })
                        .collect(),
                };
                Texels::U8 { data, lut }
            }
            Format::Float16 => Texels::F16(
                (0..samples.len())
                    .map(|i| f16::from_f32(linear(&samples, i) as f32))
                    .collect(),
            ),
            _ => Texels::F32(
                (0..samples.len())
                    .map(|i| linear(&samples, i) as f32)
                    .collect(),
            ),
        };
        let mut tex = TexImage {
            width,
            height,
            channels,
            texels,
            mean: 0.0,
            mean_rgb: Vec3::ZERO,
            coefficients: false,
        };
        tex.compute_means();
        tex
    }

    /// A three-channel texture of spectral coefficients given as they are (`width` ×
    /// `height` texels, row-major, three values each; e.g. Mitsuba's own `srgb_model_fetch`
    /// results, for comparisons), stored in f32 like [`TexImage::from_image_spectral`]'s.
    /// `None` unless there are `3 · width · height` values and at least one texel.
    pub fn from_coefficients(width: usize, height: usize, coefficients: Vec<f32>) -> Option<Self> {
        if width == 0 || height == 0 || coefficients.len() != 3 * width * height {
            return None;
        }
        let mut tex = TexImage {
            width,
            height,
            channels: 3,
            texels: Texels::F32(coefficients),
            mean: 0.0,
            mean_rgb: Vec3::ZERO,
            coefficients: true,
        };
        tex.compute_means();
        Some(tex)
    }

    /// Loads an image file as spectral mode stores it: see [`TexImage::from_image_spectral`].
    pub fn load_spectral(path: &Path, raw: bool, format: Format) -> Result<Self, String> {
        Self::from_image_spectral(image::read(path)?, raw, format)
    }

    /// The texture data as Mitsuba's spectral variants store it (`upsample_spectral`): the
    /// default storage is f32 whatever the file's depth (`format` = `auto` resolves to
    /// `variant`), 8-bit storage is refused, and unless `raw` each texel of a three-channel
    /// image becomes the coefficients of its spectrum ([`spectral::srgb_model_fetch`],
    /// which clamps the colour to [0, 1] first; rounded to half with `float16` storage, as
    /// Mitsuba stores them). One-channel images are kept as they are.
    pub fn from_image_spectral(image: Image, raw: bool, format: Format) -> Result<Self, String> {
        let storage = match format {
            Format::UInt8 => {
                return Err("format=\"uint8\" is not supported in spectral mode (8-bit storage cannot hold spectral upsampling coefficients; Mitsuba refuses it too)".into())
            }
            Format::Auto => Format::Variant,
            f => f,
        };
        let mut tex = Self::from_image(image, raw, storage);
        if tex.channels == 3 && !raw {
            use rayon::prelude::*;
            let fetch = |c: &mut [f32]| {
                let k = spectral::srgb_model_fetch([c[0], c[1], c[2]]);
                c.copy_from_slice(&k);
            };
            match &mut tex.texels {
                Texels::F32(d) => d.par_chunks_mut(3).for_each(fetch),
                Texels::F16(d) => d.par_chunks_mut(3).for_each(|c| {
                    let mut v = [c[0].to_f32(), c[1].to_f32(), c[2].to_f32()];
                    fetch(&mut v);
                    for (h, x) in c.iter_mut().zip(v) {
                        *h = f16::from_f32(x);
                    }
                }),
                Texels::U8 { .. } => unreachable!("8-bit storage is refused above"),
            }
            tex.coefficients = true;
            tex.compute_means();
        }
        Ok(tex)
    }

    fn compute_means(&mut self) {
        let n = self.width * self.height;
        let (mut lum, mut rgb) = (0.0f64, [0.0f64; 3]);
        for i in 0..n {
            if self.channels == 1 {
                let y = self.fetch::<1>(i)[0];
                lum += y as f64;
                rgb = rgb.map(|s| s + y as f64);
            } else if self.coefficients {
                // (the spectrum's mean stands for every channel)
                let m = spectral::srgb_model_mean(self.fetch::<3>(i)) as f64;
                lum += m;
                rgb = rgb.map(|s| s + m);
            } else {
                let c = self.fetch::<3>(i);
                lum += luminance(c) as f64;
                for k in 0..3 {
                    rgb[k] += c[k] as f64;
                }
            }
        }
        let n = n.max(1) as f64;
        self.mean = (lum / n) as f32;
        self.mean_rgb = Vec3::new(
            (rgb[0] / n) as f32,
            (rgb[1] / n) as f32,
            (rgb[2] / n) as f32,
        );
    }

    /// The `C` channels of texel `idx` (row-major), linear.
    #[inline(always)]
    fn fetch<const C: usize>(&self, idx: usize) -> [f32; C] {
        let base = idx * C;
        match &self.texels {
            Texels::U8 { data, lut } => std::array::from_fn(|c| lut[data[base + c] as usize]),
            Texels::F16(d) => std::array::from_fn(|c| d[base + c].to_f32()),
            Texels::F32(d) => std::array::from_fn(|c| d[base + c]),
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    /// 1 (grey) or 3 (RGB).
    pub fn channels(&self) -> usize {
        self.channels
    }
    /// Mitsuba's `mean()`: the mean grey value, or the mean luminance of RGB texels.
    pub fn mean(&self) -> f32 {
        self.mean
    }
    /// The mean of each channel (a grey value replicated).
    pub fn mean_rgb(&self) -> Vec3 {
        self.mean_rgb
    }
    /// Whether the texels hold spectral coefficients ([`TexImage::from_image_spectral`]).
    pub fn holds_coefficients(&self) -> bool {
        self.coefficients
    }
    /// The storage chosen ([`Format::Auto`] resolved).
    pub fn storage(&self) -> Format {
        match self.texels {
            Texels::U8 { .. } => Format::UInt8,
            Texels::F16(_) => Format::Float16,
            Texels::F32(_) => Format::Variant,
        }
    }
    /// Texel (x, y) (row 0 = the top of the file) as linear RGB.
    pub fn texel(&self, x: usize, y: usize) -> Vec3 {
        let i = y * self.width + x;
        if self.channels == 1 {
            Vec3::splat(self.fetch::<1>(i)[0])
        } else {
            Vec3::from(self.fetch::<3>(i))
        }
    }
}

#[inline]
fn luminance(c: [f32; 3]) -> f32 {
    crate::spectrum::luminance_rgb(glam::Vec3::from_array(c))
}

/// a·b + c rounded once, as a fused multiply-add (the product of two f32 is exact in f64;
/// the sum rounds twice only in ties far below the data's precision). `f32::mul_add` would
/// be a libm call on x86-64 without the `fma` target feature.
#[inline(always)]
fn fma(a: f32, b: f32, c: f32) -> f32 {
    (a as f64 * b as f64 + c as f64) as f32
}

/// ⌊x⌋ as an integer, saturating (NaN → 0): no input panics.
#[inline(always)]
fn floor_i64(x: f32) -> i64 {
    x.floor() as i64
}

/// Mitsuba's `to_uv` from its 4x4 `<transform>`: entries (0,0), (0,1), (0,3), (1,0), (1,1),
/// (1,3) (`Transform::extract`); the z row and column and the bottom row are dropped.
pub fn to_uv_from_4x4(m: &DMat4) -> DMat3 {
    let e = |r: usize, c: usize| m.col(c)[r];
    DMat3::from_cols(
        glam::DVec3::new(e(0, 0), e(1, 0), 0.0),
        glam::DVec3::new(e(0, 1), e(1, 1), 0.0),
        glam::DVec3::new(e(0, 3), e(1, 3), 1.0),
    )
}

/// A `bitmap` texture: shared image data, filter, wrap mode and uv transform.
#[derive(Clone, Debug)]
pub struct BitmapTexture {
    image: Arc<TexImage>,
    filter: Filter,
    wrap: Wrap,
    /// Rows (m00, m01, m02), (m10, m11, m12) of the uv transform, in f32 as Mitsuba keeps it.
    to_uv: [[f32; 3]; 2],
    identity: bool,
    /// Texel importance for [`BitmapTexture::sample_position`] (textured emitters), built by
    /// [`BitmapTexture::prepare_sampling`].
    distribution: Option<Arc<Distribution2D>>,
}

impl BitmapTexture {
    /// `to_uv` is a 2D affine transform as a 3x3 matrix acting on (u, v, 1); its bottom row
    /// is ignored. See [`to_uv_from_4x4`] for Mitsuba's 4x4 form.
    pub fn new(image: Arc<TexImage>, filter: Filter, wrap: Wrap, to_uv: DMat3) -> Self {
        let e = |r: usize, c: usize| to_uv.col(c)[r] as f32;
        let to_uv = [[e(0, 0), e(0, 1), e(0, 2)], [e(1, 0), e(1, 1), e(1, 2)]];
        let identity = to_uv == [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        BitmapTexture {
            image,
            filter,
            wrap,
            to_uv,
            identity,
            distribution: None,
        }
    }

    /// The gradient of [`BitmapTexture::eval_1`] with respect to (u, v), as Mitsuba's
    /// `eval_1_grad` (bump maps): the slope of the bilinear patch, zero for nearest lookups.
    /// Mitsuba multiplies the pixel-space slope by the transpose of `to_uv`'s 2x2 block and
    /// then by the resolution per axis (exact for a `to_uv` without rotation or shear).
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        if self.filter == Filter::Nearest {
            return Vec2::ZERO;
        }
        let (u, v) = self.transform(uv);
        let img = &*self.image;
        let (w, h) = (img.width, img.height);
        let px = fma(u, w as f32, -0.5);
        let py = fma(v, h as f32, -0.5);
        let (fx, fy) = (px.floor(), py.floor());
        let (wx1, wy1) = (px - fx, py - fy);
        let (wx0, wy0) = (1.0 - wx1, 1.0 - wy1);
        let (ix, iy) = (floor_i64(fx), floor_i64(fy));
        let xs = [
            self.wrap.apply(ix, w),
            self.wrap.apply(ix.saturating_add(1), w),
        ];
        let ys = [
            self.wrap.apply(iy, h),
            self.wrap.apply(iy.saturating_add(1), h),
        ];
        let value = |x: usize, y: usize| -> f32 {
            if img.channels == 1 {
                img.fetch::<1>(y * w + x)[0]
            } else {
                luminance(img.fetch::<3>(y * w + x))
            }
        };
        let (f00, f10) = (value(xs[0], ys[0]), value(xs[1], ys[0]));
        let (f01, f11) = (value(xs[0], ys[1]), value(xs[1], ys[1]));
        let dfx = fma(wy0, f10 - f00, wy1 * (f11 - f01));
        let dfy = fma(wx0, f01 - f00, wx1 * (f11 - f10));
        let m = &self.to_uv;
        Vec2::new(
            w as f32 * (m[0][0] * dfx + m[1][0] * dfy),
            h as f32 * (m[0][1] * dfx + m[1][1] * dfy),
        )
    }

    /// Builds the texel distribution that [`BitmapTexture::sample_position`] draws from:
    /// each texel in proportion to its value (grey or luminance), as Mitsuba's
    /// `init_distr`. A texture with nothing positive is sampled uniformly.
    pub fn prepare_sampling(&mut self) {
        let img = &*self.image;
        let weights: Vec<f64> = (0..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .map(|(x, y)| {
                let t = img.texel(x, y);
                let v = if img.channels == 1 {
                    t.x
                } else if img.coefficients {
                    spectral::srgb_model_mean(t.to_array())
                } else {
                    luminance(t.to_array())
                };
                if v.is_finite() && v > 0.0 {
                    v as f64
                } else {
                    0.0
                }
            })
            .collect();
        self.distribution = Distribution2D::new(&weights, img.width, img.height).map(Arc::new);
    }

    /// A point of [0, 1]² (before `to_uv`, as in Mitsuba) drawn in proportion to the
    /// texels' values, and its density: a texel picked by value, then uniformly in it
    /// (nearest) or by a tent over the texel and its neighbours (bilinear, folded back into
    /// [0, 1] at the edges), so that the density is the lookup's own interpolation of the
    /// texels' probabilities. Uniform until [`BitmapTexture::prepare_sampling`].
    pub fn sample_position(&self, u: Vec2) -> (Vec2, f32) {
        let Some(dist) = &self.distribution else {
            return (u, 1.0);
        };
        let Some((i, j, r)) = dist.sample_cell(u) else {
            return (u, 0.0);
        };
        let (w, h) = (self.image.width as f32, self.image.height as f32);
        let uv = match self.filter {
            Filter::Nearest => Vec2::new((i as f32 + r.x) / w, (j as f32 + r.y) / h),
            Filter::Bilinear => {
                let fold = |x: f32| match self.wrap {
                    Wrap::Repeat => {
                        if x < 0.0 {
                            x + 1.0
                        } else if x > 1.0 {
                            x - 1.0
                        } else {
                            x
                        }
                    }
                    Wrap::Clamp | Wrap::Mirror => {
                        if x < 0.0 {
                            -x
                        } else if x > 1.0 {
                            2.0 - x
                        } else {
                            x
                        }
                    }
                };
                let tent = Distribution2D::square_to_tent;
                Vec2::new(
                    fold((i as f32 + 0.5 + tent(r.x)) / w),
                    fold((j as f32 + 0.5 + tent(r.y)) / h),
                )
            }
        };
        (uv, self.pdf_position(uv))
    }

    /// The density of [`BitmapTexture::sample_position`] at `uv` (w.r.t. area on [0, 1]²).
    pub fn pdf_position(&self, uv: Vec2) -> f32 {
        let Some(dist) = &self.distribution else {
            return 1.0;
        };
        let (w, h) = (self.image.width, self.image.height);
        let texels = (w * h) as f64;
        let p = match self.filter {
            Filter::Nearest => {
                let x = self.wrap.apply(floor_i64(uv.x * w as f32), w);
                let y = self.wrap.apply(floor_i64(uv.y * h as f32), h);
                dist.pmf(x, y)
            }
            Filter::Bilinear => {
                let px = uv.x * w as f32 - 0.5;
                let py = uv.y * h as f32 - 0.5;
                let (fx, fy) = (px.floor(), py.floor());
                let (wx1, wy1) = ((px - fx) as f64, (py - fy) as f64);
                let (ix, iy) = (floor_i64(fx), floor_i64(fy));
                let pmf = |dx: i64, dy: i64| {
                    dist.pmf(
                        self.wrap.apply(ix.saturating_add(dx), w),
                        self.wrap.apply(iy.saturating_add(dy), h),
                    )
                };
                (1.0 - wy1) * ((1.0 - wx1) * pmf(0, 0) + wx1 * pmf(1, 0))
                    + wy1 * ((1.0 - wx1) * pmf(0, 1) + wx1 * pmf(1, 1))
            }
        };
        (p * texels) as f32
    }

    /// Linear RGB at `uv` (a grey image's value replicated).
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        if self.image.channels == 1 {
            Vec3::splat(self.lookup::<1>(uv)[0])
        } else {
            Vec3::from(self.lookup::<3>(uv))
        }
    }

    /// The value at `uv` and `wavelengths` (nm), as Mitsuba's `eval` in its spectral variants:
    /// a grey image's value at every wavelength; for coefficient texels
    /// ([`TexImage::from_image_spectral`]) the spectra of the texels evaluated at the
    /// wavelengths and then interpolated (the upsampling is not linear: interpolating the
    /// colours or the coefficients first would give another spectrum), in Mitsuba's order of
    /// fused multiply-adds; nearest: the one texel's spectrum. Any other image (RGB mode, or a
    /// `raw` three-channel image, which the scene builder refuses in spectral mode) gives
    /// its RGB lanes.
    #[inline]
    pub fn eval_spectrum(&self, uv: Vec2, wavelengths: glam::Vec4) -> glam::Vec4 {
        if !self.image.coefficients {
            return crate::spectrum::from_rgb(self.eval(uv));
        }
        let spectrum = |c: [f32; 3]| spectral::srgb_model_eval(c, wavelengths);
        let (u, v) = self.transform(uv);
        let img = &*self.image;
        let (w, h) = (img.width, img.height);
        match self.filter {
            Filter::Nearest => {
                let x = self.wrap.apply(floor_i64(u * w as f32), w);
                let y = self.wrap.apply(floor_i64(v * h as f32), h);
                spectrum(img.fetch::<3>(y * w + x))
            }
            Filter::Bilinear => {
                let px = fma(u, w as f32, -0.5);
                let py = fma(v, h as f32, -0.5);
                let (fx, fy) = (px.floor(), py.floor());
                let (wx1, wy1) = (px - fx, py - fy);
                let (wx0, wy0) = (1.0 - wx1, 1.0 - wy1);
                let (ix, iy) = (floor_i64(fx), floor_i64(fy));
                let (x0, x1) = (
                    self.wrap.apply(ix, w),
                    self.wrap.apply(ix.saturating_add(1), w),
                );
                let (y0, y1) = (
                    self.wrap.apply(iy, h),
                    self.wrap.apply(iy.saturating_add(1), h),
                );
                let s = |x: usize, y: usize| spectrum(img.fetch::<3>(y * w + x));
                // c0 = fma(w0x, c00, w1x c10), c1 likewise, fma(w0y, c0, w1y c1)
                let lerp = |w0: f32, a: glam::Vec4, w1: f32, b: glam::Vec4| {
                    let p = b * w1;
                    glam::Vec4::from_array(std::array::from_fn(|k| fma(w0, a[k], p[k])))
                };
                let c0 = lerp(wx0, s(x0, y0), wx1, s(x1, y0));
                let c1 = lerp(wx0, s(x0, y1), wx1, s(x1, y1));
                lerp(wy0, c0, wy1, c1)
            }
        }
    }

    /// Whether the texels hold spectral coefficients (spectral mode, three channels, not
    /// `raw`): such a texture answers spectral lookups only; Mitsuba refuses `eval_1` and
    /// `eval_3` of it.
    pub fn holds_coefficients(&self) -> bool {
        self.image.coefficients
    }

    /// One value at `uv`, as Mitsuba's `eval_1`: the grey value, or the luminance of the
    /// interpolated RGB (roughness, opacity, bump height, ...).
    pub fn eval_1(&self, uv: Vec2) -> f32 {
        if self.image.channels == 1 {
            self.lookup::<1>(uv)[0]
        } else {
            luminance(self.lookup::<3>(uv))
        }
    }

    /// Mitsuba's `mean()`: the mean grey value or mean luminance over the texels.
    pub fn mean(&self) -> f32 {
        self.image.mean
    }

    /// The mean of each channel over the texels (a grey value replicated).
    pub fn mean_rgb(&self) -> Vec3 {
        self.image.mean_rgb
    }

    /// 1 (grey) or 3 (RGB).
    pub fn channels(&self) -> usize {
        self.image.channels
    }

    /// (width, height) in texels.
    pub fn resolution(&self) -> (usize, usize) {
        (self.image.width, self.image.height)
    }

    pub fn image(&self) -> &Arc<TexImage> {
        &self.image
    }
    pub fn filter(&self) -> Filter {
        self.filter
    }
    pub fn wrap(&self) -> Wrap {
        self.wrap
    }

    #[inline]
    fn transform(&self, uv: Vec2) -> (f32, f32) {
        if self.identity {
            return (uv.x, uv.y);
        }
        let m = &self.to_uv;
        (
            fma(m[0][1], uv.y, fma(m[0][0], uv.x, m[0][2])),
            fma(m[1][1], uv.y, fma(m[1][0], uv.x, m[1][2])),
        )
    }

    #[inline]
    fn lookup<const C: usize>(&self, uv: Vec2) -> [f32; C] {
        let (u, v) = self.transform(uv);
        let img = &*self.image;
        let (w, h) = (img.width, img.height);
        match self.filter {
            Filter::Nearest => {
                let x = self.wrap.apply(floor_i64(u * w as f32), w);
                let y = self.wrap.apply(floor_i64(v * h as f32), h);
                img.fetch::<C>(y * w + x)
            }
            Filter::Bilinear => {
                let px = fma(u, w as f32, -0.5);
                let py = fma(v, h as f32, -0.5);
                let (fx, fy) = (px.floor(), py.floor());
                let (wx1, wy1) = (px - fx, py - fy);
                let wx = [1.0 - wx1, wx1];
                let wy = [1.0 - wy1, wy1];
                let (ix, iy) = (floor_i64(fx), floor_i64(fy));
                let xs = [
                    self.wrap.apply(ix, w),
                    self.wrap.apply(ix.saturating_add(1), w),
                ];
                let ys = [
                    self.wrap.apply(iy, h),
                    self.wrap.apply(iy.saturating_add(1), h),
                ];
                let mut acc = [0.0f32; C];
                for (y, wy) in ys.iter().zip(wy) {
                    for (x, wx) in xs.iter().zip(wx) {
                        let weight = wx * wy;
                        let t = img.fetch::<C>(y * w + x);
                        for c in 0..C {
                            acc[c] = fma(t[c], weight, acc[c]);
                        }
                    }
                }
                acc
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn repo(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
    }

    struct Case {
        name: String,
        file: String,
        raw: bool,
        filter: Filter,
        wrap: Wrap,
        format: Format,
        channels: usize,
        res: (usize, usize),
        mean: f32,
        to_uv: [f64; 6],
        /// u, v, eval (r, g, b), eval_1
        points: Vec<([f32; 2], [f32; 3], f32)>,
    }

    fn mitsuba_cases() -> Vec<Case> {
        let text = std::fs::read_to_string(repo("tests/data/mitsuba_bitmap_lookups.txt")).unwrap();
        let mut cases: Vec<Case> = Vec::new();
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            let f: Vec<&str> = line.split_whitespace().collect();
            let num = |s: &str| s.parse::<f32>().unwrap();
            match f[0] {
                "case" => cases.push(Case {
                    name: f[1].into(),
                    file: f[2].into(),
                    raw: f[3] == "1",
                    filter: Filter::from_name(f[4]).unwrap(),
                    wrap: Wrap::from_name(f[5]).unwrap(),
                    format: Format::from_name(f[6]).unwrap(),
                    channels: f[7].parse().unwrap(),
                    res: (f[8].parse().unwrap(), f[9].parse().unwrap()),
                    mean: num(f[10]),
                    to_uv: std::array::from_fn(|i| f[11 + i].parse::<f64>().unwrap()),
                    points: Vec::new(),
                }),
                "p" => {
                    let uv = [num(f[1]), num(f[2])];
                    let p = if f.len() == 4 {
                        (uv, [num(f[3]); 3], num(f[3]))
                    } else {
                        (uv, [num(f[3]), num(f[4]), num(f[5])], num(f[6]))
                    };
                    cases.last_mut().unwrap().points.push(p);
                }
                _ => panic!("bad line {line}"),
            }
        }
        cases
    }

    /// Means over the texels: Mitsuba's in its scalar variants (summed in f32, in order),
    /// and summed in f64.
    fn reference_means(img: &TexImage) -> (f32, f64) {
        let (mut sum32, mut sum64) = (0.0f32, 0.0f64);
        for y in 0..img.height() {
            for x in 0..img.width() {
                let t = img.texel(x, y);
                let v = if img.channels() == 1 {
                    t.x
                } else {
                    luminance(t.to_array())
                };
                sum32 += v;
                sum64 += v as f64;
            }
        }
        let n = img.width() * img.height();
        (sum32 / n as f32, sum64 / n as f64)
    }

    /// (file, raw, format) of a loaded test image
    type ImageKey = (String, bool, Format);
    /// the image and its reference means (f32 sum, f64 sum)
    type LoadedImage = (Arc<TexImage>, (f32, f64));

    /// Every lookup of validation/mitsuba/bitmap_lookups.py, and every mean.
    ///
    /// Tolerance 1e-6 x max(1, |value|) (about 8 f32 ulps at 1): penumbra decodes sRGB with
    /// the exact curve where Mitsuba uses a rational fit (within 4e-7), and its fused
    /// multiply-adds are emulated in f64 (a second rounding in rare ties), Mitsuba's compiler
    /// may contract the luminance differently. Measured worst: 4.2e-7.
    ///
    /// JPEG: 3 codes (x 2.3, the steepest slope of the sRGB decode, unless raw). The decoders
    /// differ: zune-jpeg against Mitsuba's libjpeg, measured on the suite's 2048² photos,
    /// 99.1% of samples equal, the rest within 3 codes (IDCT and chroma upsampling rounding).
    ///
    /// Means: Mitsuba's scalar variant sums the texels in f32, off by up to 1.3% of the mean
    /// on a 2048² texture (floor_tiles_normalmap.jpg); penumbra sums in f64. So the test
    /// checks that Mitsuba's number is the f32 sum of penumbra's texels, and that penumbra's
    /// mean differs from it by no more than that f32 sum's own error.
    #[test]
    fn agrees_with_mitsuba_lookups() {
        let cases = mitsuba_cases();
        assert!(cases.len() > 100);
        let mut images: HashMap<ImageKey, LoadedImage> = HashMap::new();
        let mut checked = 0;
        for c in &cases {
            let (image, (f32_mean, f64_mean)) = images
                .entry((c.file.clone(), c.raw, c.format))
                .or_insert_with(|| {
                    let img = TexImage::load_with_format(&repo(&c.file), c.raw, c.format).unwrap();
                    let means = reference_means(&img);
                    (Arc::new(img), means)
                })
                .clone();
            let m = c.to_uv;
            let to_uv = DMat3::from_cols(
                glam::DVec3::new(m[0], m[3], 0.0),
                glam::DVec3::new(m[1], m[4], 0.0),
                glam::DVec3::new(m[2], m[5], 1.0),
            );
            let tex = BitmapTexture::new(image.clone(), c.filter, c.wrap, to_uv);
            assert_eq!(tex.channels(), c.channels, "{}", c.name);
            // Mitsuba pads images below 2x2 (no effect on lookups)
            let (w, h) = tex.resolution();
            assert_eq!((w.max(2), h.max(2)), c.res, "{}", c.name);

            let jpeg = c.file.ends_with(".jpg");
            let tol = if jpeg {
                3.0 / 255.0 * if c.raw { 1.0 } else { 2.3 }
            } else {
                1e-6
            };
            let close = |a: f32, b: f32| (a - b).abs() <= tol * b.abs().max(1.0);
            assert!(
                jpeg || close(f32_mean, c.mean),
                "{}: f32 sum of the texels {f32_mean}, Mitsuba's mean {}",
                c.name,
                c.mean
            );
            assert!(
                (tex.mean() as f64 - f64_mean).abs() <= 1e-7 * f64_mean.abs().max(1.0),
                "{}: mean {} vs the texels' {f64_mean}",
                c.name,
                tex.mean()
            );
            assert!(
                (f64_mean - c.mean as f64).abs() <= (f64_mean - f32_mean as f64).abs() + tol as f64,
                "{}: mean {f64_mean} vs Mitsuba's {} (its f32 sum: {f32_mean})",
                c.name,
                c.mean
            );
            for (uv, rgb, e1) in &c.points {
                let uv = Vec2::from(*uv);
                let (got, got1) = (tex.eval(uv), tex.eval_1(uv));
                assert!(
                    (0..3).all(|k| close(got[k], rgb[k])) && close(got1, *e1),
                    "{} at uv {uv}: eval {got} eval_1 {got1}, Mitsuba {rgb:?} {e1}",
                    c.name
                );
                checked += 1;
            }
        }
        assert!(checked > 6000);
    }

    #[test]
    fn wrap_modes_per_texel_index() {
        let seq = |w: Wrap, n: usize| (-5..9).map(|i| w.apply(i, n)).collect::<Vec<_>>();
        assert_eq!(
            seq(Wrap::Repeat, 4),
            [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]
        );
        assert_eq!(
            seq(Wrap::Mirror, 4),
            [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]
        );
        assert_eq!(
            seq(Wrap::Clamp, 4),
            [0, 0, 0, 0, 0, 0, 1, 2, 3, 3, 3, 3, 3, 3]
        );
        for w in [Wrap::Repeat, Wrap::Mirror, Wrap::Clamp] {
            assert!(seq(w, 1).iter().all(|&i| i == 0));
            assert!(w.apply(i64::MAX, 7) < 7 && w.apply(i64::MIN, 7) < 7);
        }
    }

    #[test]
    fn to_uv_keeps_mitsubas_entries_of_a_4x4() {
        // the "general" transform of validation/mitsuba/bitmap_lookups.py, row-major
        let rows = [
            [1.5, 0.25, 7.0, -0.3],
            [-0.5, 2.0, 9.0, 0.6],
            [3.0, 4.0, 5.0, 6.0],
            [0.1, 0.2, 0.3, 1.0],
        ];
        let m = DMat4::from_cols_array_2d(&rows).transpose();
        let t = to_uv_from_4x4(&m);
        let case = mitsuba_cases()
            .into_iter()
            .find(|c| c.name == "rgb8_png-to_uv-general")
            .unwrap();
        let got = [
            t.col(0)[0],
            t.col(1)[0],
            t.col(2)[0],
            t.col(0)[1],
            t.col(1)[1],
            t.col(2)[1],
        ];
        for (g, e) in got.iter().zip(case.to_uv) {
            assert_eq!(*g as f32, e as f32);
        }
        assert_eq!(t.row(2), glam::DVec3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn parameter_names() {
        assert_eq!(Filter::from_name("nearest"), Ok(Filter::Nearest));
        assert_eq!(Wrap::from_name("mirror"), Ok(Wrap::Mirror));
        assert_eq!(Format::from_name("fp16"), Ok(Format::Float16));
        assert!(Filter::from_name("bicubic").is_err());
        assert!(Wrap::from_name("border").is_err());
        assert!(Format::from_name("float32").is_err());
        assert_eq!(Filter::default(), Filter::Bilinear);
        assert_eq!(Wrap::default(), Wrap::Repeat);
        assert_eq!(Format::default(), Format::Auto);
    }

    fn grey(width: usize, samples: Samples) -> Image {
        Image {
            width,
            height: samples.len() / width,
            channels: 1,
            samples,
            format: image::FileFormat::Exr,
            layout: image::Layout::Y,
        }
    }

    #[test]
    fn storage_formats() {
        let f = || Samples::F32(vec![-1.0, 0.5, 2.0, f32::NAN]);
        let auto = TexImage::from_image(grey(4, f()), false, Format::Auto);
        assert_eq!(auto.storage(), Format::Variant);
        assert_eq!(auto.texel(2, 0).x, 2.0);
        // float data to 8 bits: clamped, linear, rounded (Mitsuba dithers), NaN to 0
        let u8s = TexImage::from_image(grey(4, f()), false, Format::UInt8);
        let vals: Vec<f32> = (0..4).map(|x| u8s.texel(x, 0).x).collect();
        assert_eq!(
            vals,
            [
                0.0,
                128.0 * (1.0f32 / 255.0),
                1.0 * (255.0 * (1.0f32 / 255.0)),
                0.0
            ]
        );
        let h = TexImage::from_image(grey(4, f()), false, Format::Float16);
        assert_eq!(h.storage(), Format::Float16);
        assert_eq!(h.texel(1, 0).x, 0.5);
        // 16-bit data: half by default, sRGB-decoded unless raw; to 8 bits stays encoded
        let u16s = || Samples::U16(vec![0, 32768, 65535, 13107]);
        let a = TexImage::from_image(grey(4, u16s()), false, Format::Auto);
        assert_eq!(a.storage(), Format::Float16);
        let exact = srgb_to_linear(13107.0 / 65535.0) as f32;
        assert!((a.texel(3, 0).x - exact).abs() <= exact * 1e-3);
        let r = TexImage::from_image(grey(4, u16s()), true, Format::Auto);
        assert!((r.texel(3, 0).x - 0.2).abs() < 1e-4);
        let q = TexImage::from_image(grey(4, u16s()), false, Format::UInt8);
        assert_eq!(q.texel(2, 0).x, srgb_to_linear(1.0) as f32);
        assert!((q.texel(3, 0).x - srgb_to_linear(51.0 / 255.0) as f32).abs() < 1e-7);
        // 8-bit data: kept as codes, decoded through the table
        let b = TexImage::from_image(grey(2, Samples::U8(vec![0, 255])), false, Format::Auto);
        assert_eq!(b.storage(), Format::UInt8);
        assert_eq!((b.texel(0, 0).x, b.texel(1, 0).x), (0.0, 1.0));
    }

    #[test]
    fn means() {
        let img = Image {
            width: 2,
            height: 1,
            channels: 3,
            samples: Samples::F32(vec![1.0, 0.0, 0.5, 0.0, 0.5, 0.5]),
            format: image::FileFormat::Exr,
            layout: image::Layout::Rgb,
        };
        let t = TexImage::from_image(img, false, Format::Auto);
        assert_eq!(t.mean_rgb(), Vec3::new(0.5, 0.25, 0.5));
        let lum = 0.212671 * 0.5 + 0.715160 * 0.25 + 0.072169 * 0.5; // Mitsuba's weights
        assert!((t.mean() - lum).abs() < 1e-7);
        let g = TexImage::from_image(grey(2, Samples::U8(vec![255, 0])), false, Format::Auto);
        assert_eq!((g.mean(), g.mean_rgb()), (0.5, Vec3::splat(0.5)));
    }

    #[test]
    fn odd_uvs_never_panic() {
        let one = Arc::new(TexImage::from_image(
            grey(1, Samples::U8(vec![7])),
            false,
            Format::Auto,
        ));
        let rgb = Arc::new(TexImage::load(&repo("tests/data/textures/rgb8.png"), false).unwrap());
        let odd = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e30,
            -1e30,
            f32::MAX,
            f32::MIN_POSITIVE,
            -0.0,
        ];
        for img in [one, rgb] {
            for filter in [Filter::Bilinear, Filter::Nearest] {
                for wrap in [Wrap::Repeat, Wrap::Mirror, Wrap::Clamp] {
                    let scale = DMat3::from_scale(glam::DVec2::new(1e20, -3.0));
                    for to_uv in [DMat3::IDENTITY, scale] {
                        let t = BitmapTexture::new(img.clone(), filter, wrap, to_uv);
                        for u in odd {
                            for v in [0.5, u] {
                                let _ = (t.eval(Vec2::new(u, v)), t.eval_1(Vec2::new(v, u)));
                            }
                        }
                    }
                }
            }
        }
    }
}
