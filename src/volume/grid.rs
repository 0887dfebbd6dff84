//! Mitsuba's `gridvolume`: values on a regular grid read from a `.vol` file
//! ([`crate::io::vol`]), looked up with trilinear interpolation (or nearest neighbour) between
//! sample points at the cell centres of the unit cube, as Dr.Jit's textures do.
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `filename` | `.vol` file, 1 or 3 channels | required |
//! | `filter_type` | `trilinear` or `nearest` | `trilinear` |
//! | `wrap_mode` | `clamp`, `repeat` or `mirror` | `clamp` |
//! | `use_grid_bbox` | the file's box places the grid (after `to_world`) | false |
//! | `raw` | keep three channels as numbers in spectral mode (then they cannot be looked up as a spectrum) | false |
//! | `to_world` | transform of the unit cube | identity |
//!
//! A world point p is looked up at local coordinates `to_local · p` (to_local = to_world⁻¹,
//! preceded by the map of the file's box to the unit cube with `use_grid_bbox`); outside
//! [0, 1]³ the wrap mode decides. One-channel grids evaluate to grey RGB.
//!
//! In spectral mode a three-channel grid holds spectra, as Mitsuba 3.9.1's `gridvolume`
//! converts it at load ([`GridVolume::to_spectral`]): each cell's colour `c` becomes the scale
//! `s = 2 max(c)` and the sigmoid-polynomial coefficients of `c / max(s, 1e-8)` (a reflectance
//! in [0, ½], so every cell's spectrum lies in [0, s]); the grid's largest value becomes the
//! largest `s`. A trilinear lookup interpolates the eight cells' *spectra* and, separately,
//! their scales, and multiplies the two; a nearest lookup is the cell's `s · S(λ)`.
//!
//! ```xml
//! <volume type="gridvolume" name="sigma_t">
//!     <string name="filename" value="textures/sigmat.vol"/>
//! </volume>
//! ```

use crate::io::vol::VolData;
use crate::spectral::{srgb_model_eval, Coefficients};
use crate::texture::bitmap::Wrap;
use glam::{Mat4, Vec3, Vec4};

/// The cells one lookup reads ([`GridVolume::cells`]).
enum Cells {
    Nearest([usize; 3]),
    /// Cells `xs × ys × zs`; `w1` the weights of the upper ones (`1 − w1` the lower ones').
    Trilinear {
        xs: [usize; 2],
        ys: [usize; 2],
        zs: [usize; 2],
        w1: Vec3,
    },
}

#[derive(Clone, Debug)]
pub struct GridVolume {
    res: [usize; 3],
    /// 1 or 3.
    channels: usize,
    data: Vec<f32>,
    /// World → unit-cube texture coordinates.
    to_local: Mat4,
    trilinear: bool,
    wrap: Wrap,
    /// Largest value of any channel.
    pub max: f32,
    /// Spectral mode, three channels: per cell the sigmoid coefficients and the scale.
    spectral: Option<Vec<[f32; 4]>>,
    /// World-space box of the grid.
    pub bbox: [Vec3; 2],
}

impl GridVolume {
    /// A grid volume of `vol`'s values; `Err` for a channel count other than 1 or 3, a
    /// non-finite value or a singular transform.
    pub fn new(
        vol: VolData,
        to_world: Mat4,
        use_grid_bbox: bool,
        trilinear: bool,
        wrap: Wrap,
    ) -> Result<Self, String> {
        if vol.channels != 1 && vol.channels != 3 {
            return Err(format!(
                "a gridvolume needs 1 or 3 channels, the file has {}",
                vol.channels
            ));
        }
        if let Some(v) = vol.data.iter().find(|v| !v.is_finite()) {
            return Err(format!("the grid holds a non-finite value ({v})"));
        }
        let mut to_local = to_world.inverse();
        if use_grid_bbox {
            let lo = Vec3::from(vol.bbox[0]);
            let hi = Vec3::from(vol.bbox[1]);
            let ext = hi - lo;
            if ext.min_element().is_nan() || ext.min_element() <= 0.0 || !ext.is_finite() {
                return Err(format!(
                    "use_grid_bbox: the file's bounding box {lo} .. {hi} is empty"
                ));
            }
            to_local = Mat4::from_scale(ext.recip()) * Mat4::from_translation(-lo) * to_local;
        }
        if !to_local.is_finite() {
            return Err("the gridvolume's to_world is singular".into());
        }
        let local_to_world = to_local.inverse();
        let max = vol.data.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        Ok(GridVolume {
            res: vol.res,
            channels: vol.channels,
            bbox: super::unit_cube_bbox(&local_to_world),
            data: vol.data,
            to_local,
            trilinear,
            wrap,
            max,
            spectral: None,
        })
    }

    /// Converts a three-channel grid's cells into spectra for spectral mode (see the module's
    /// documentation) and sets [`GridVolume::max`] to the largest scale; a one-channel grid
    /// is unchanged (its value is the same at every wavelength).
    pub fn to_spectral(&mut self) {
        self.to_spectral_with(crate::spectral::srgb_model_fetch);
    }

    /// [`GridVolume::to_spectral`] with the upsampling `fetch` given (called once per cell,
    /// in the cells' order: tests hand Mitsuba's own coefficients in).
    pub fn to_spectral_with(&mut self, mut fetch: impl FnMut([f32; 3]) -> Coefficients) {
        if self.channels != 3 || self.spectral.is_some() {
            return;
        }
        let mut max = 0.0f32;
        let cells = self
            .data
            .chunks_exact(3)
            .map(|c| {
                let cell =
                    crate::spectral::scaled_coefficients_with([c[0], c[1], c[2]], &mut fetch);
                max = max.max(cell[3]);
                cell
            })
            .collect();
        self.spectral = Some(cells);
        self.max = max;
    }

    /// Whether the cells hold spectra ([`GridVolume::to_spectral`]).
    #[inline]
    pub fn is_spectral(&self) -> bool {
        self.spectral.is_some()
    }

    /// The spectrum at world-space point `p` and `wavelengths` of a grid converted by
    /// [`GridVolume::to_spectral`] (zero for any other grid).
    pub fn eval_spectral(&self, p: Vec3, wavelengths: Vec4) -> Vec4 {
        let Some(cells) = &self.spectral else {
            return Vec4::ZERO;
        };
        let cell = |[x, y, z]: [usize; 3]| cells[(z * self.res[1] + y) * self.res[0] + x];
        let spectrum = |c: [f32; 4]| srgb_model_eval([c[0], c[1], c[2]], wavelengths);
        let (xs, ys, zs, w1) = match self.cells(p) {
            None => return Vec4::ZERO,
            Some(Cells::Nearest(at)) => {
                let c = cell(at);
                return spectrum(c) * c[3];
            }
            Some(Cells::Trilinear { xs, ys, zs, w1 }) => (xs, ys, zs, w1),
        };
        let w0 = Vec3::ONE - w1;
        // Along x, then y, then z: the spectra and the scales separately.
        let mut v = [[Vec4::ZERO; 2]; 2];
        let mut s = [[0.0f32; 2]; 2];
        for (k, z) in zs.iter().enumerate() {
            for (j, y) in ys.iter().enumerate() {
                let (a, b) = (cell([xs[0], *y, *z]), cell([xs[1], *y, *z]));
                v[k][j] = spectrum(a) * w0.x + spectrum(b) * w1.x;
                s[k][j] = a[3] * w0.x + b[3] * w1.x;
            }
        }
        let v0 = v[0][0] * w0.y + v[0][1] * w1.y;
        let v1 = v[1][0] * w0.y + v[1][1] * w1.y;
        let s0 = s[0][0] * w0.y + s[0][1] * w1.y;
        let s1 = s[1][0] * w0.y + s[1][1] * w1.y;
        (v0 * w0.z + v1 * w1.z) * (s0 * w0.z + s1 * w1.z)
    }

    /// Values per cell: 1 or 3.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The mean of the cells' values (a one-channel grid's as grey).
    pub fn mean(&self) -> Vec3 {
        let cells = self.data.len() / self.channels;
        let mut sum = [0.0f64; 3];
        for cell in self.data.chunks_exact(self.channels) {
            for (c, s) in sum.iter_mut().enumerate() {
                *s += cell[c.min(self.channels - 1)] as f64;
            }
        }
        let n = cells.max(1) as f64;
        Vec3::new(
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
        )
    }

    #[inline]
    fn fetch(&self, x: usize, y: usize, z: usize) -> Vec3 {
        let i = ((z * self.res[1] + y) * self.res[0] + x) * self.channels;
        if self.channels == 1 {
            Vec3::splat(self.data[i])
        } else {
            Vec3::new(self.data[i], self.data[i + 1], self.data[i + 2])
        }
    }

    /// The cells a lookup at world-space point `p` reads, after the wrap mode: one (nearest)
    /// or the eight around it with the upper cells' trilinear weights; `None` where `p` maps
    /// to no finite grid coordinates.
    #[inline]
    fn cells(&self, p: Vec3) -> Option<Cells> {
        let q = self.to_local.transform_point3(p);
        if !q.is_finite() {
            return None;
        }
        let [nx, ny, nz] = self.res;
        if !self.trilinear {
            let x = self.wrap.apply((q.x * nx as f32).floor() as i64, nx);
            let y = self.wrap.apply((q.y * ny as f32).floor() as i64, ny);
            let z = self.wrap.apply((q.z * nz as f32).floor() as i64, nz);
            return Some(Cells::Nearest([x, y, z]));
        }
        let pos = q * Vec3::new(nx as f32, ny as f32, nz as f32) - 0.5;
        let f0 = pos.floor();
        let i0 = [f0.x as i64, f0.y as i64, f0.z as i64];
        Some(Cells::Trilinear {
            xs: [self.wrap.apply(i0[0], nx), self.wrap.apply(i0[0] + 1, nx)],
            ys: [self.wrap.apply(i0[1], ny), self.wrap.apply(i0[1] + 1, ny)],
            zs: [self.wrap.apply(i0[2], nz), self.wrap.apply(i0[2] + 1, nz)],
            w1: pos - f0,
        })
    }

    /// The value at world-space point `p`.
    #[inline]
    pub fn eval(&self, p: Vec3) -> Vec3 {
        let (xs, ys, zs, w1) = match self.cells(p) {
            None => return Vec3::ZERO,
            Some(Cells::Nearest([x, y, z])) => return self.fetch(x, y, z),
            Some(Cells::Trilinear { xs, ys, zs, w1 }) => (xs, ys, zs, w1),
        };
        let wx = [1.0 - w1.x, w1.x];
        let wy = [1.0 - w1.y, w1.y];
        let wz = [1.0 - w1.z, w1.z];
        let mut acc = Vec3::ZERO;
        for (z, wz) in zs.iter().zip(wz) {
            for (y, wy) in ys.iter().zip(wy) {
                for (x, wx) in xs.iter().zip(wx) {
                    acc += self.fetch(*x, *y, *z) * (wx * wy * wz);
                }
            }
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2×1×1 grid with values 1 and 3: texel centres at x = 0.25 and 0.75.
    fn two_texels(to_world: Mat4, use_grid_bbox: bool, trilinear: bool) -> GridVolume {
        let vol = VolData {
            res: [2, 1, 1],
            channels: 1,
            bbox: [[-1.0, 0.0, 0.0], [1.0, 1.0, 1.0]],
            data: vec![1.0, 3.0],
        };
        GridVolume::new(vol, to_world, use_grid_bbox, trilinear, Wrap::Clamp).unwrap()
    }

    #[test]
    fn trilinear_lookup_interpolates_between_texel_centres_and_clamps() {
        let g = two_texels(Mat4::IDENTITY, false, true);
        let at = |x: f32| g.eval(Vec3::new(x, 0.5, 0.5)).x;
        assert_eq!(at(0.25), 1.0);
        assert_eq!(at(0.75), 3.0);
        assert_eq!(at(0.5), 2.0);
        assert_eq!(at(0.375), 1.5);
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(-3.0), 1.0);
        assert_eq!(at(7.0), 3.0);
        assert_eq!(g.max, 3.0);
        assert_eq!(g.bbox, [Vec3::ZERO, Vec3::ONE]);
    }

    /// A 2×2×2 grid holding v = 1 + 2i + 4j + 8k at texel (i, j, k) (x fastest in the data),
    /// a different value at each texel. Trilinear interpolation reproduces a function linear
    /// in the texel coordinates exactly: inside the texel centres v(q) = 1 + 2p_x + 4p_y +
    /// 8p_z with p = 2q − ½; the nearest lookup returns the texel of ⌊2q⌋. Every axis and the
    /// data layout enter.
    #[test]
    fn lookups_interpolate_and_pick_along_every_axis() {
        let data: Vec<f32> = (0..8)
            .map(|n| {
                let (i, j, k) = (n % 2, (n / 2) % 2, n / 4);
                (1 + 2 * i + 4 * j + 8 * k) as f32
            })
            .collect();
        let vol = |trilinear| {
            let v = VolData {
                res: [2, 2, 2],
                channels: 1,
                bbox: [[0.0; 3], [1.0; 3]],
                data: data.clone(),
            };
            GridVolume::new(v, Mat4::IDENTITY, false, trilinear, Wrap::Clamp).unwrap()
        };
        let (tri, nearest) = (vol(true), vol(false));
        for q in [
            Vec3::new(0.3, 0.6, 0.45),
            Vec3::new(0.7, 0.26, 0.74),
            Vec3::new(0.5, 0.5, 0.5),
            Vec3::new(0.25, 0.75, 0.6),
        ] {
            let p = q * 2.0 - 0.5;
            let want = 1.0 + 2.0 * p.x + 4.0 * p.y + 8.0 * p.z;
            let got = tri.eval(q).x;
            assert!(
                (got - want).abs() < 1e-5,
                "trilinear at {q}: {got} vs {want}"
            );
            let cell = (q * 2.0).floor();
            let want = 1.0 + 2.0 * cell.x + 4.0 * cell.y + 8.0 * cell.z;
            assert_eq!(nearest.eval(q).x, want, "nearest at {q}");
        }
    }

    #[test]
    fn nearest_lookup_picks_the_cell() {
        let g = two_texels(Mat4::IDENTITY, false, false);
        assert_eq!(g.eval(Vec3::new(0.49, 0.5, 0.5)).x, 1.0);
        assert_eq!(g.eval(Vec3::new(0.51, 0.5, 0.5)).x, 3.0);
    }

    #[test]
    fn to_world_and_grid_bbox_place_the_grid() {
        // to_world = scale 2 then translate (1, 0, 0): the unit cube becomes [1, 3] × [0, 2]².
        let m = Mat4::from_translation(Vec3::X) * Mat4::from_scale(Vec3::splat(2.0));
        let g = two_texels(m, false, true);
        assert_eq!(g.bbox, [Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, 2.0, 2.0)]);
        assert_eq!(g.eval(Vec3::new(2.0, 1.0, 1.0)).x, 2.0);
        assert_eq!(g.eval(Vec3::new(1.5, 1.0, 1.0)).x, 1.0);
        // With the file's box [-1, 1] × [0, 1]²: world x = -0.5 is the first texel's centre.
        let g = two_texels(Mat4::IDENTITY, true, true);
        assert_eq!(g.bbox, [Vec3::new(-1.0, 0.0, 0.0), Vec3::ONE]);
        assert_eq!(g.eval(Vec3::new(-0.5, 0.5, 0.5)).x, 1.0);
        assert_eq!(g.eval(Vec3::new(0.0, 0.5, 0.5)).x, 2.0);
    }

    #[test]
    fn three_channel_grids_keep_their_channels_and_bad_channel_counts_are_refused() {
        let vol = VolData {
            res: [1, 1, 1],
            channels: 3,
            bbox: [[0.0; 3], [1.0; 3]],
            data: vec![0.1, 0.2, 0.7],
        };
        let g = GridVolume::new(vol, Mat4::IDENTITY, false, true, Wrap::Clamp).unwrap();
        let v = g.eval(Vec3::splat(0.3));
        assert!(
            (v - Vec3::new(0.1, 0.2, 0.7)).abs().max_element() < 1e-6,
            "{v}"
        );
        assert_eq!(g.max, 0.7);
        let vol = VolData {
            res: [1, 1, 1],
            channels: 2,
            bbox: [[0.0; 3], [1.0; 3]],
            data: vec![0.1, 0.2],
        };
        assert!(GridVolume::new(vol, Mat4::IDENTITY, false, true, Wrap::Clamp).is_err());
    }

    /// Spectral mode, as Mitsuba's `gridvolume`: a cell (r, g, b) holds s = 2 max(r, g, b) and
    /// the spectrum of (r, g, b) / s; a grey cell is its value at every wavelength; a trilinear
    /// lookup is (interpolated spectra) × (interpolated scales), not the interpolation of the
    /// products; a nearest lookup the cell's s · S(λ); the majorant the largest s.
    #[test]
    fn spectral_cells_hold_scaled_spectra_interpolated_apart_from_their_scales() {
        use crate::spectral::{srgb_model_eval, srgb_model_fetch};
        let grid = |trilinear| {
            let vol = VolData {
                res: [2, 1, 1],
                channels: 3,
                bbox: [[0.0; 3], [1.0; 3]],
                data: vec![0.3, 0.3, 0.3, 0.9, 0.2, 0.05],
            };
            let mut g =
                GridVolume::new(vol, Mat4::IDENTITY, false, trilinear, Wrap::Clamp).unwrap();
            g.to_spectral();
            g
        };
        let (tri, nearest) = (grid(true), grid(false));
        assert!(tri.is_spectral());
        assert_eq!(tri.max, 1.8);
        let wl = Vec4::new(400.0, 480.0, 560.0, 700.0);
        // The grey cell: S = ½ at every wavelength, s = 0.6.
        let grey = tri.eval_spectral(Vec3::new(0.25, 0.5, 0.5), wl);
        assert!(
            (grey - Vec4::splat(0.3)).abs().max_element() < 1e-6,
            "{grey}"
        );
        let red = srgb_model_eval(srgb_model_fetch([0.5, 0.2 / 1.8, 0.05 / 1.8]), wl);
        let got = nearest.eval_spectral(Vec3::new(0.8, 0.5, 0.5), wl);
        assert!(
            (got - red * 1.8).abs().max_element() < 1e-6,
            "{got} vs {}",
            red * 1.8
        );
        // Halfway between the cells' centres.
        let mid = tri.eval_spectral(Vec3::new(0.5, 0.5, 0.5), wl);
        let want = (Vec4::splat(0.5) + red) * 0.5 * ((0.6 + 1.8) * 0.5);
        assert!((mid - want).abs().max_element() < 1e-6, "{mid} vs {want}");
        let products = (Vec4::splat(0.3) + red * 1.8) * 0.5;
        assert!(
            (mid - products).abs().max_element() > 1e-3,
            "the two forms differ here"
        );
        // A one-channel grid is left as it is.
        let mut one = two_texels(Mat4::IDENTITY, false, true);
        one.to_spectral();
        assert!(!one.is_spectral());
        assert_eq!(one.max, 3.0);
    }
}
