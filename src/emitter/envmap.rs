//! Mitsuba's `envmap` emitter: radiance at infinity from a latitude-longitude image, times
//! `scale`, rotated by `to_world`.
//!
//! Parameterisation, measured on Mitsuba 3.9.1 by evaluating the plugin on random directions
//! (agreement to 1e-6 with this mapping): for a local direction (x, y, z), +y is up,
//! u = atan2(x, −z) / 2π (mod 1) and v = acos(y) / π. Bilinear lookup: columns are texel
//! centres, x = u W − ½, wrapping around; rows are spread from pole to pole, y = v (H − 1),
//! so the first row is the radiance straight up and the last straight down.
//!
//! Importance sampling, as Mitsuba's (`warp::Marginal2D` over the texels): a density in
//! (u, v) bilinear between the texel centres (W columns, the first repeated after the last,
//! by H rows; [`Bilinear2D`]), its value at each texel the texel's luminance times sin θ of
//! its row, so that the density per solid angle, p(u, v) / (2π² sin θ), follows the
//! bilinearly interpolated radiance. Until 2026-12-05 the density was constant over each
//! cell between texels (the cell's mean luminance times its solid angle): at equal spp the
//! environment-lit Cornell box had 1.22× the MSE of Mitsuba's image.
//!
//! Spectral mode (Mitsuba's spectral variants, [`EnvMapEmitter::new_spectral`]): each texel
//! is stored as the coefficients of the spectrum of its colour over s = 2 max(R, G, B)
//! (a reflectance whose largest channel is ½) and s; the radiance is the four corner
//! texels' spectra interpolated bilinearly, times the interpolated s, times `scale`, times
//! the normalised D65 illuminant. The sampling density weighs each texel by the mean of its
//! spectrum times s instead of the luminance.

use super::DirectionSample;
use crate::sampling::Bilinear2D;
use crate::spectral::{self, D65Emission};
use crate::spectrum::{from_rgb, Spectrum};
use glam::{Mat3, Vec2, Vec3, Vec4};
use std::f32::consts::PI;

pub use crate::spectrum::luminance;

#[derive(Clone, Debug)]
pub struct EnvMapEmitter {
    width: usize,
    height: usize,
    /// Row-major texels (row 0 = up), already multiplied by `scale` (RGB mode; empty in
    /// spectral mode).
    texels: Vec<Spectrum>,
    /// Spectral mode's texels.
    spectral: Option<Box<SpectralTexels>>,
    to_world: Mat3,
    to_local: Mat3,
    distribution: Option<Bilinear2D>,
    mean_radiance: f64,
}

/// Spectral mode's texels: per texel the coefficients of the spectrum of rgb / s and s =
/// 2 max(rgb) (Mitsuba's four-channel texture), the `scale` and the D65 illuminant.
#[derive(Clone, Debug)]
struct SpectralTexels {
    texels: Vec<[f32; 4]>,
    scale: f32,
    d65: D65Emission,
}

impl EnvMapEmitter {
    /// `texels` row-major from the top row; `to_world` a rotation. Needs at least 2 rows.
    pub fn new(
        width: usize,
        height: usize,
        texels: &[[f32; 3]],
        scale: f32,
        to_world: Mat3,
    ) -> Option<Self> {
        if width == 0 || height < 2 || texels.len() != width * height {
            return None;
        }
        let texels: Vec<Spectrum> = texels
            .iter()
            .map(|t| from_rgb(Vec3::from(*t) * scale))
            .collect();
        let lum: Vec<f64> = texels
            .iter()
            .map(|t| luminance(*t).max(0.0) as f64)
            .collect();
        let mean_rgb: Vec<f64> = texels
            .iter()
            .map(|t| (t.x as f64 + t.y as f64 + t.z as f64) / 3.0)
            .collect();
        Some(Self::with_weights(
            width, height, texels, None, &lum, &mean_rgb, to_world,
        ))
    }

    /// Spectral mode's envmap, as Mitsuba's spectral variants build it: each texel's colour
    /// `rgb` becomes the coefficients of rgb / max(10⁻⁸, s) ([`spectral::srgb_model_fetch`])
    /// and s = 2 max(rgb); see the top. Same arguments as [`EnvMapEmitter::new`].
    pub fn new_spectral(
        width: usize,
        height: usize,
        texels: &[[f32; 3]],
        scale: f32,
        to_world: Mat3,
    ) -> Option<Self> {
        use rayon::prelude::*;
        let coeffs: Vec<[f32; 4]> = texels
            .par_iter()
            .map(|t| spectral::scaled_coefficients(*t))
            .collect();
        Self::from_spectral_texels(width, height, coeffs, scale, to_world)
    }

    /// Spectral mode's envmap from texels already in the form of
    /// [`spectral::scaled_coefficients`] (e.g. Mitsuba's own coefficients, for comparisons).
    pub fn from_spectral_texels(
        width: usize,
        height: usize,
        coeffs: Vec<[f32; 4]>,
        scale: f32,
        to_world: Mat3,
    ) -> Option<Self> {
        if width == 0 || height < 2 || coeffs.len() != width * height {
            return None;
        }
        // Mitsuba's sampling weight: the spectrum's mean times s (times the scale here).
        let lum: Vec<f64> = coeffs
            .iter()
            .map(|c| {
                let m = spectral::srgb_model_mean([c[0], c[1], c[2]]) as f64 * c[3] as f64;
                (m * scale as f64).max(0.0)
            })
            .collect();
        Some(Self::with_weights(
            width,
            height,
            Vec::new(),
            Some(Box::new(SpectralTexels {
                texels: coeffs,
                scale,
                d65: D65Emission::new(1.0),
            })),
            &lum,
            &lum,
            to_world,
        ))
    }

    /// The emitter with its sampling distribution: `lum` the texels' sampling weights,
    /// `mean_vals` their mean values (for the mean radiance).
    fn with_weights(
        width: usize,
        height: usize,
        texels: Vec<Spectrum>,
        spectral: Option<Box<SpectralTexels>>,
        lum: &[f64],
        mean_rgb: &[f64],
        to_world: Mat3,
    ) -> Self {
        let at = |v: &[f64], i: usize, j: usize| v[j * width + (i % width)];
        let (nu, nv) = (width, height - 1);
        let mut mean = 0.0;
        let cos_row = |j: usize| (std::f64::consts::PI * j as f64 / nv as f64).cos();
        for j in 0..nv {
            let band = cos_row(j) - cos_row(j + 1);
            for i in 0..nu {
                let corners = |v: &[f64]| {
                    (at(v, i, j) + at(v, i + 1, j) + at(v, i, j + 1) + at(v, i + 1, j + 1)) / 4.0
                };
                mean += corners(mean_rgb) * band * 2.0 * std::f64::consts::PI / nu as f64;
            }
        }
        // The sampling density's vertices: each texel's weight times sin θ of its row (the
        // density per solid angle is the bilinear interpolation over sin θ), the first
        // column repeated after the last.
        let vertices: Vec<f64> = (0..height)
            .flat_map(|j| {
                let sin_t = (std::f64::consts::PI * j as f64 / nv as f64).sin().max(0.0);
                (0..=nu).map(move |i| at(lum, i, j) * sin_t)
            })
            .collect();
        EnvMapEmitter {
            width,
            height,
            texels,
            spectral,
            to_world,
            to_local: to_world.inverse(),
            distribution: Bilinear2D::new(&vertices, nu, nv),
            mean_radiance: mean / (4.0 * std::f64::consts::PI),
        }
    }

    /// Mean radiance over the sphere of directions (mean over RGB).
    pub fn mean_radiance(&self) -> f64 {
        self.mean_radiance
    }

    fn texel(&self, i: i64, j: usize) -> Spectrum {
        let i = i.rem_euclid(self.width as i64) as usize;
        self.texels[j * self.width + i]
    }

    /// (u, v) of a world direction, and sin θ.
    fn uv(&self, d: Vec3) -> (Vec2, f32) {
        let l = (self.to_local * d).normalize_or_zero();
        let u = (crate::math::atan2f(l.x, -l.z) * (0.5 / PI)).rem_euclid(1.0);
        // θ and sin θ from the other two components: √(1 − y²) and acos(y) cancel
        // catastrophically near the poles (26 of 300k samples had a pdf() 0.1–8% off the
        // sampled one there).
        // √(x² + z²) in f64, rounded once (as glibc's hypotf computes it, without libm)
        let (x, z) = (l.x as f64, l.z as f64);
        let sin_t = (x * x + z * z).sqrt() as f32;
        let v = crate::math::atan2f(sin_t, l.y) / PI;
        (Vec2::new(u, v), sin_t)
    }

    /// Radiance arriving from direction −`d` (`d` the escaping ray's direction), at the
    /// wavelengths `wl` in spectral mode (ignored in RGB mode).
    pub fn eval(&self, d: Vec3, wl: Vec4) -> Spectrum {
        self.eval_uv(self.uv(d).0, wl)
    }

    /// [`EnvMapEmitter::eval`] and [`EnvMapEmitter::pdf_direction`] at once, the direction's
    /// (u, v) found once (what a path escaping the scene needs: its uv was a third of the
    /// instructions of an environment-lit Cornell box's paths, computed twice).
    pub fn eval_with_pdf(&self, d: Vec3, wl: Vec4) -> (Spectrum, f32) {
        let (uv, sin_t) = self.uv(d);
        (self.eval_uv(uv, wl), self.pdf_uv(uv, sin_t))
    }

    /// The radiance at (u, v).
    fn eval_uv(&self, uv: Vec2, wl: Vec4) -> Spectrum {
        if let Some(sp) = &self.spectral {
            return self.eval_spectral(sp, uv, wl);
        }
        let x = uv.x * self.width as f32 - 0.5;
        let y = (uv.y * (self.height - 1) as f32).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (x.floor(), (y.floor() as usize).min(self.height - 2));
        let (fx, fy) = (x - x0, y - y0 as f32);
        let x0 = x0 as i64;
        let top = self.texel(x0, y0) * (1.0 - fx) + self.texel(x0 + 1, y0) * fx;
        let bottom = self.texel(x0, y0 + 1) * (1.0 - fx) + self.texel(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Spectral mode's radiance at (u, v), in Mitsuba's arithmetic (`eval_spectrum`): the
    /// lookup position goes through the coordinates of its texture, which has one halo
    /// column on each side (a copy of the opposite edge) and clamps: pos = ((u W + 1) / (W
    /// + 2), (v (H − 1) + ½) / H), texel coordinates pos · (W + 2, H) − ½.
    fn eval_spectral(&self, sp: &SpectralTexels, uv: Vec2, wl: Vec4) -> Spectrum {
        let fma = |a: f32, b: f32, c: f32| (a as f64 * b as f64 + c as f64) as f32;
        let (w, h) = (self.width as f32, self.height as f32);
        let u = uv.x - uv.x.floor();
        let v = uv.y.clamp(0.0, 1.0);
        let pos = Vec2::new(fma(u, w, 1.0) / (w + 2.0), fma(v, h - 1.0, 0.5) / h);
        let pf = Vec2::new(fma(pos.x, w + 2.0, -0.5), fma(pos.y, h, -0.5));
        let fl = pf.floor();
        let (w1, w0) = (pf - fl, Vec2::ONE - (pf - fl));
        let (sx, sy) = (fl.x as i64, fl.y as i64);
        // storage column c (0..=W+1) holds real column c − 1, the halo the opposite edge
        let col = |c: i64| -> usize {
            let c = c.clamp(0, self.width as i64 + 1);
            (c - 1).rem_euclid(self.width as i64) as usize
        };
        let row = |r: i64| r.clamp(0, self.height as i64 - 1) as usize;
        let (x0, x1, y0, y1) = (col(sx), col(sx + 1), row(sy), row(sy + 1));
        let t = |x: usize, y: usize| sp.texels[y * self.width + x];
        let (c00, c10, c01, c11) = (t(x0, y0), t(x1, y0), t(x0, y1), t(x1, y1));
        let spec = |c: [f32; 4]| spectral::srgb_model_eval([c[0], c[1], c[2]], wl);
        let lerp4 = |w0: f32, a: Vec4, w1: f32, b: Vec4| {
            let p = b * w1;
            Vec4::from_array(std::array::from_fn(|k| fma(w0, a[k], p[k])))
        };
        let s0 = lerp4(w0.x, spec(c00), w1.x, spec(c10));
        let s1 = lerp4(w0.x, spec(c01), w1.x, spec(c11));
        let f0 = fma(w0.x, c00[3], w1.x * c10[3]);
        let f1 = fma(w0.x, c01[3], w1.x * c11[3]);
        let s = lerp4(w0.y, s0, w1.y, s1);
        let f = fma(w0.y, f0, w1.y * f1);
        s * f * sp.scale * sp.d65.eval(wl)
    }

    pub fn sample_direction(&self, u: Vec2, wl: Vec4) -> Option<DirectionSample> {
        let dist = self.distribution.as_ref()?;
        let (cell_uv, pdf_uv) = dist.sample(u);
        if pdf_uv <= 0.0 {
            return None;
        }
        // Cells start half a texel to the right of u = 0.
        let uu = (cell_uv.x + 0.5 / self.width as f32).rem_euclid(1.0);
        let theta = cell_uv.y * PI;
        let phi = uu * 2.0 * PI;
        let (sin_t, cos_t) = crate::math::sin_cosf(theta);
        if sin_t <= 0.0 {
            return None;
        }
        let (sin_p, cos_p) = crate::math::sin_cosf(phi);
        let local = Vec3::new(sin_t * sin_p, cos_t, -sin_t * cos_p);
        let d = (self.to_world * local).normalize();
        let pdf = pdf_uv / (2.0 * PI * PI * sin_t);
        (pdf.is_finite() && pdf > 0.0).then(|| DirectionSample {
            p: Vec3::ZERO,
            p_error: Vec3::ZERO,
            n: Vec3::ZERO,
            d,
            dist: f32::INFINITY,
            pdf,
            // the radiance at the sampled (u, v), not at uv(d): the same up to rounding, and
            // the direction's atan2s were a third of this function's instructions
            radiance: self.eval_uv(Vec2::new(uu, cell_uv.y), wl),
            delta: false,
        })
    }

    /// Solid-angle density of `sample_direction` at the escaping direction `d`.
    pub fn pdf_direction(&self, d: Vec3) -> f32 {
        let (uv, sin_t) = self.uv(d);
        self.pdf_uv(uv, sin_t)
    }

    /// The solid-angle density at (u, v), with sin θ.
    fn pdf_uv(&self, uv: Vec2, sin_t: f32) -> f32 {
        let Some(dist) = &self.distribution else {
            return 0.0;
        };
        if sin_t <= 0.0 {
            return 0.0;
        }
        let cu = (uv.x - 0.5 / self.width as f32).rem_euclid(1.0);
        dist.pdf(Vec2::new(cu, uv.y)) / (2.0 * PI * PI * sin_t)
    }

    /// The local-to-world rotation.
    pub fn to_world(&self) -> Mat3 {
        self.to_world
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The direction whose (u, v) is given: the inverse of `uv` for the identity rotation.
    fn direction(u: f32, v: f32) -> Vec3 {
        let (st, ct) = (PI * v).sin_cos();
        let (sp, cp) = (2.0 * PI * u).sin_cos();
        Vec3::new(st * sp, ct, -st * cp)
    }

    /// Bilinear lookups as documented at the top: a texel's value at its centre (columns at
    /// u = (i + ½)/W, rows at v = j/(H − 1)), the mean of the four around a cell's middle,
    /// wrapping around in u (the pole rows, where u is undefined, left out); independent of
    /// the sampling code.
    /// A uniform map's mean radiance over the sphere is its value (the mean over RGB, times
    /// the scale): what its power, and so SPPM's choice of emitter, is made of.
    #[test]
    fn a_uniform_map_has_its_value_as_mean_radiance() {
        let (w, h) = (8, 5);
        let texels = vec![[0.2f32, 0.4, 0.6]; w * h];
        let e = EnvMapEmitter::new(w, h, &texels, 2.0, Mat3::IDENTITY).unwrap();
        let want = 2.0 * (0.2 + 0.4 + 0.6) / 3.0;
        assert!(
            (e.mean_radiance() - want).abs() < 1e-6 * want,
            "{}",
            e.mean_radiance()
        );
    }

    #[test]
    fn eval_interpolates_texel_centres_bilinearly() {
        let (w, h) = (4, 4);
        let texels: Vec<[f32; 3]> = (0..w * h)
            .map(|k| [1.0 + k as f32, 2.0 * k as f32 + 0.5, (k * k) as f32])
            .collect();
        let e = EnvMapEmitter::new(w, h, &texels, 2.0, Mat3::IDENTITY).unwrap();
        let t = |i: usize, j: usize| from_rgb(Vec3::from(texels[j * w + i % w]) * 2.0);
        for j in 1..h - 1 {
            for i in 0..w {
                let d = direction((i as f32 + 0.5) / w as f32, j as f32 / (h - 1) as f32);
                let got = e.eval(d, Vec4::ZERO);
                assert!(
                    (got - t(i, j)).abs().max_element() < 1e-3,
                    "texel ({i}, {j}): {got}"
                );
            }
        }
        for j in 0..h - 1 {
            for i in 0..w {
                let d = direction(
                    (i as f32 + 1.0) / w as f32,
                    (j as f32 + 0.5) / (h - 1) as f32,
                );
                let want = (t(i, j) + t(i + 1, j) + t(i, j + 1) + t(i + 1, j + 1)) / 4.0;
                let got = e.eval(d, Vec4::ZERO);
                assert!(
                    (got - want).abs().max_element() < 1e-3,
                    "cell ({i}, {j}): {got} vs {want}"
                );
            }
        }
    }

    /// What an escaping path looks up at once is what the separate calls give, bit for bit,
    /// in both modes and with a rotation (the lane engine's images equal the scalar
    /// engine's, and the MIS weight of an escape must use the density `pdf_direction`
    /// gives).
    #[test]
    fn eval_with_pdf_is_eval_and_pdf_direction() {
        let (w, h) = (8, 5);
        let texels: Vec<[f32; 3]> = (0..w * h)
            .map(|k| [0.1 + k as f32, (k % 7) as f32, 0.5 * (k % 3) as f32])
            .collect();
        let rot = Mat3::from_rotation_y(0.5) * Mat3::from_rotation_x(0.3);
        let rgb = EnvMapEmitter::new(w, h, &texels, 1.5, rot).unwrap();
        let spectral = EnvMapEmitter::new_spectral(w, h, &texels, 1.5, rot).unwrap();
        let wl = Vec4::new(420.0, 510.0, 600.0, 690.0);
        let mut n = 0;
        for e in [&rgb, &spectral] {
            for k in 0..200 {
                let u = (k as f32 + 0.5) / 200.0;
                let d = rot * direction(u, (k as f32 * 0.618).fract());
                let (le, pdf) = e.eval_with_pdf(d, wl);
                assert_eq!(
                    le.to_array().map(f32::to_bits),
                    e.eval(d, wl).to_array().map(f32::to_bits)
                );
                assert_eq!(pdf.to_bits(), e.pdf_direction(d).to_bits(), "{d}");
                n += (pdf > 0.0 && le.max_element() > 0.0) as usize;
            }
        }
        assert!(n > 300, "{n} lookups with light and density");
    }

    /// A sample's radiance is looked up at the sampled (u, v), not at its direction's: it
    /// must still be the radiance from that direction, `eval(d)`, up to rounding: within
    /// 10⁻⁴ of the map's largest value (the direction's u carries its rounding divided by
    /// sin θ, times the map's contrast per texel; samples within sin θ < 0.05 of the poles,
    /// where that grows unbounded, are left out). Red with the sample's half-texel shift
    /// left out of the lookup (most samples off by a good part of the contrast), in both
    /// modes.
    #[test]
    fn a_samples_radiance_is_the_radiance_from_its_direction() {
        let (w, h) = (16, 9);
        let texels: Vec<[f32; 3]> = (0..w * h)
            .map(|k| {
                [
                    1.0 + (k % 5) as f32,
                    0.2 + (k % 11) as f32,
                    3.0 * (k % 2) as f32,
                ]
            })
            .collect();
        let rot = Mat3::from_rotation_z(0.7) * Mat3::from_rotation_y(-1.1);
        let wl = Vec4::new(450.0, 520.0, 580.0, 640.0);
        for e in [
            EnvMapEmitter::new(w, h, &texels, 2.0, rot).unwrap(),
            EnvMapEmitter::new_spectral(w, h, &texels, 2.0, rot).unwrap(),
        ] {
            // the largest radiance: at a texel centre
            let largest = (0..w * h)
                .map(|k| {
                    let d = rot
                        * direction(
                            (k % w) as f32 / w as f32 + 0.5 / w as f32,
                            (k / w) as f32 / (h - 1) as f32,
                        );
                    e.eval(d, wl).max_element()
                })
                .fold(0.0f32, f32::max);
            let mut n = 0;
            for k in 0..4096u32 {
                let u = Vec2::new(
                    (k as f32 + 0.5) / 4096.0,
                    (k.wrapping_mul(2654435769) >> 8) as f32 / (1 << 24) as f32,
                );
                let Some(ds) = e.sample_direction(u, wl) else {
                    continue;
                };
                let (_, sin_t) = e.uv(ds.d);
                if sin_t < 0.05 {
                    continue;
                }
                n += 1;
                let want = e.eval(ds.d, wl);
                let err = (ds.radiance - want).abs().max_element();
                assert!(
                    err <= 1e-4 * largest,
                    "sample {k}: {} vs eval(d) {want}",
                    ds.radiance
                );
            }
            assert!(n > 3500, "{n} samples");
        }
    }
}
