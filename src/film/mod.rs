//! Mitsuba's `hdrfilm` accumulation, in f64: per pixel the weighted sum of sample values, of
//! their squares (for the per-pixel variance) and of the filter weights. Samples are placed
//! uniformly in their pixel and splatted to the pixels within the reconstruction filter's
//! radius; the weights are divided out at the end. Each render tile accumulates into its own
//! [`FilmTile`] (its pixels plus a border of the filter radius), and tiles are merged in a
//! fixed order, so the sums are bit-identical whatever the thread count.
//!
//! # The order of accumulation (issue 42)
//!
//! Within one pass the sums are *not* independent of the order of the samples: a tile adds
//! each sample's w·f, w·f², w²·f, w²·f², w, w² and w³ to its pixels' f64 sums one sample after
//! another ([`FilmTile::add_sample`]), and f64 addition is not associative, so the same
//! samples added in another order can give other last bits. [`Film::merge`] then adds the
//! tiles' sums (which overlap by the filter's border) in the fixed tile order of
//! `render::render`, and only the pass film is added exactly ([`ExactFilm::add`]: the
//! grouping of passes and parts does not matter). So an image is a function of its samples
//! only because `render::render_tile` adds them in one canonical order: the tile's pixels
//! row by row (y, then x, from the tile's corner, the border of `sample_border` included),
//! and per pixel the sample indices ascending, non-finite samples left out (counted).
//!
//! An engine whose paths finish out of order (the lane engine) must keep that order per
//! tile: store each finished sample's film position and value (20 B) at its canonical index
//! (pixel within the tile × spp + sample), and call [`FilmTile::add_sample`] in index order,
//! either when the tile's samples are all done (at most 16 × 16 × 256 samples, 1.3 MB, for
//! images of up to 32² pixels, where a pass holds 256 spp; 80 KB at 128²) or as a window
//! that adds a sample once all before it are done. Making the tile's sums exact instead
//! would cost 15 exact additions per pixel a sample reaches (12–20 ns each,
//! docs/performance.md, 2026-12-02), several µs per sample with the default gaussian filter
//! (16 pixels) against about 1 µs per path.

use glam::{Vec2, Vec3};

pub mod exact;
pub use exact::{ExactError, ExactFilm, ExactSum, EXACT_VALUES};

/// Reconstruction filters (Mitsuba's `rfilter`), all separable: w(x, y) = w(x) w(y), with x
/// and y in pixels from a pixel's centre.
///
/// Splat weights are the filter's exact values, as in Mitsuba 3.9.1's JIT variants
/// (`llvm_ad_rgb`, which renders the references): measured with `ImageBlock.put`, its weights
/// equal `rfilter.eval`. (Its scalar variants splat with `eval_discretized` instead, a
/// 32-entry step table, which blurs slightly more.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// Mitsuba's `box` with its default radius 0.5: each sample counts for the pixel it falls
    /// in, with weight 1.
    Box,
    /// Mitsuba's `tent`: w(x) = max(0, 1 − |x| / radius) (default radius 1).
    Tent { radius: f64 },
    /// Mitsuba's `gaussian` (the default filter): radius 4 σ, w(x) = max(0, exp(−x²/2σ²) −
    /// exp(−r²/2σ²)), shifted down to reach 0 at the radius (default σ = 0.5 px).
    Gaussian { stddev: f64 },
}

impl Filter {
    /// Mitsuba's default: gaussian with σ = 0.5 pixel.
    pub const DEFAULT: Filter = Filter::Gaussian { stddev: 0.5 };

    /// Support radius in pixels.
    pub fn radius(&self) -> f64 {
        match *self {
            Filter::Box => 0.5,
            Filter::Tent { radius } => radius,
            Filter::Gaussian { stddev } => 4.0 * stddev,
        }
    }

    /// How many pixels beyond its own a sample can reach.
    pub fn border(&self) -> usize {
        match self {
            Filter::Box => 0,
            _ => (self.radius() - 0.5).ceil().max(0.0) as usize,
        }
    }

    /// The continuous 1D filter (Mitsuba's `eval`), unnormalised.
    pub fn eval(&self, x: f64) -> f64 {
        let x = x.abs();
        match *self {
            Filter::Box => {
                if x <= 0.5 {
                    1.0
                } else {
                    0.0
                }
            }
            Filter::Tent { radius } => (1.0 - x / radius).max(0.0),
            Filter::Gaussian { stddev } => {
                let a = -0.5 / (stddev * stddev);
                let r = 4.0 * stddev;
                (crate::math::exp(a * x * x) - crate::math::exp(a * r * r)).max(0.0)
            }
        }
    }

    /// The 1D splatting weight at offset `x` from a pixel centre (0 from the radius on; the
    /// box filter: 1 inside the pixel).
    #[inline]
    pub fn weight(&self, x: f64) -> f64 {
        if x.abs() >= self.radius() {
            0.0
        } else {
            self.eval(x)
        }
    }

    /// ∫ weight(x − c)^p dx over film positions x ∈ [lo, hi] (composite Simpson rule on the
    /// part inside the support, with the box filter's integral exact).
    pub fn weight_moment(&self, c: f64, lo: f64, hi: f64, p: i32) -> f64 {
        let r = self.radius();
        let (a, b) = (lo.max(c - r), hi.min(c + r));
        if b <= a {
            return 0.0;
        }
        if let Filter::Box = self {
            return b - a;
        }
        // The tent's kink at c: integrate each side separately so the rule stays exact
        // for the tent and accurate to ~1e-12 for the gaussian.
        let simpson = |a: f64, b: f64| -> f64 {
            if b <= a {
                return 0.0;
            }
            crate::math::simpson(|x| self.weight(x - c).powi(p), a, b, 2000)
        };
        simpson(a, b.min(c)) + simpson(a.max(c), b)
    }

    /// ∫ w² / (∫ w)² over the part of the pixel's footprint inside [0, n] (one axis). With
    /// samples uniform over the image at `spp` per pixel, a pixel's filtered estimate has
    /// variance σ² · factor_x · factor_y / spp for per-sample variance σ² (1 for the box
    /// filter; smaller for wider filters; larger at the border).
    pub fn variance_factor_1d(&self, pixel: usize, n: usize) -> f64 {
        let c = pixel as f64 + 0.5;
        let w1 = self.weight_moment(c, 0.0, n as f64, 1);
        let w2 = self.weight_moment(c, 0.0, n as f64, 2);
        if w1 > 0.0 {
            w2 / (w1 * w1)
        } else {
            0.0
        }
    }
}

/// The pixels [first, first + count) of one axis that a sample at `pos` reaches through
/// `filter` of radius `r`, with their weights.
#[inline]
fn axis_weights(filter: Filter, pos: f64, r: f64, out: &mut [f64; 16]) -> (i64, usize) {
    let first = (pos - 0.5 - r).floor() as i64 + 1;
    let last = (pos - 0.5 + r).ceil() as i64 - 1;
    let count = ((last - first + 1).max(0) as usize).min(out.len());
    for (k, w) in out.iter_mut().enumerate().take(count) {
        let d = ((first + k as i64) as f64 + 0.5 - pos).abs();
        *w = if d < r { filter.eval(d) } else { 0.0 };
    }
    (first, count)
}

/// One pass of an integrator whose samples reach the film both as filtered camera samples
/// (at their own pixel sample's position) and as light-traced splats (anywhere): the
/// bidirectional path tracer. Every pixel of the window has one sample position per pass
/// (its pixel sample), so a pass holds, per pixel, the filter-weighted sum Σ w f and weight
/// Σ w of the camera samples that reach it and the sum L of the splats that reach it.
/// [`Film::add_mixed_pass`] adds it as one sample per pixel of weight Σ w and value
/// Σ w f / Σ w + L: the camera part of the image is then Mitsuba's ratio estimator
/// Σ w f / Σ w over all passes, exactly as for the path tracer, and the splats' part the
/// (Σ w)-weighted mean of the passes' L.
///
/// A splat at film position x adds v · w(x − c) / N_c to pixel c, with N_c = ∫ w(y − c) dy
/// over the region camera samples are drawn from (the window and the `sample_border`
/// beyond it): the expectation of the splats is then the same filtered integral of the
/// image as the camera samples' ratio estimator, ∫ I(y) w(y − c) dy / N_c, also at the
/// edges where the filter's footprint leaves that region. (Normalising each splat by its
/// own footprint, as [`Film::splat`] does, darkens the edge pixels of a wide filter.)
#[derive(Clone, Debug)]
pub struct MixedPass {
    width: usize,
    height: usize,
    filter: Filter,
    sum: Vec<[f64; 3]>,
    weight: Vec<f64>,
    splat: Vec<[f64; 3]>,
    /// 1 / N per column and per row (the filter is separable).
    inv_norm_x: Vec<f64>,
    inv_norm_y: Vec<f64>,
}

impl MixedPass {
    /// An empty pass of a `width` x `height` image sampled `border` pixels beyond its edges.
    pub fn new(width: usize, height: usize, filter: Filter, border: usize) -> Self {
        let b = border as f64;
        let inv_norm = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| {
                    let norm = filter.weight_moment(i as f64 + 0.5, -b, n as f64 + b, 1);
                    if norm > 0.0 {
                        1.0 / norm
                    } else {
                        0.0
                    }
                })
                .collect()
        };
        MixedPass {
            width,
            height,
            filter,
            sum: vec![[0.0; 3]; width * height],
            weight: vec![0.0; width * height],
            splat: vec![[0.0; 3]; width * height],
            inv_norm_x: inv_norm(width),
            inv_norm_y: inv_norm(height),
        }
    }

    /// Empties the pass for the next one.
    pub fn clear(&mut self) {
        self.sum.iter_mut().for_each(|p| *p = [0.0; 3]);
        self.weight.iter_mut().for_each(|p| *p = 0.0);
        self.splat.iter_mut().for_each(|p| *p = [0.0; 3]);
    }

    /// Adds a camera sample of value `v` at film position `pos` (pixels).
    pub fn add_sample(&mut self, pos: Vec2, v: Vec3) {
        spread(self.filter, self.width, self.height, pos, |i, wt, _, _| {
            for c in 0..3 {
                self.sum[i][c] += wt * v[c] as f64;
            }
            self.weight[i] += wt;
        });
    }

    /// Adds a light-traced splat of value `v` at film position `pos` (pixels).
    pub fn add_splat(&mut self, pos: Vec2, v: Vec3) {
        spread(self.filter, self.width, self.height, pos, |i, wt, x, y| {
            let k = wt * self.inv_norm_x[x] * self.inv_norm_y[y];
            for c in 0..3 {
                self.splat[i][c] += k * v[c] as f64;
            }
        });
    }
}

/// Calls `put(pixel index, weight, x, y)` for the pixels of a `width` x `height` image
/// that a sample at `pos` (pixels) reaches through `filter`, with the filter's weight
/// (as [`FilmTile::add_sample`] spreads it).
#[inline]
fn spread(
    filter: Filter,
    width: usize,
    height: usize,
    pos: Vec2,
    mut put: impl FnMut(usize, f64, usize, usize),
) {
    let (w, h) = (width as i64, height as i64);
    if filter == Filter::Box {
        let (x, y) = (pos.x.floor() as i64, pos.y.floor() as i64);
        if x >= 0 && y >= 0 && x < w && y < h {
            put((x + y * w) as usize, 1.0, x as usize, y as usize);
        }
        return;
    }
    let r = filter.radius();
    let (mut wx, mut wy) = ([0.0; 16], [0.0; 16]);
    let (fx, nx) = axis_weights(filter, pos.x as f64, r, &mut wx);
    let (fy, ny) = axis_weights(filter, pos.y as f64, r, &mut wy);
    for (ky, &wyk) in wy.iter().enumerate().take(ny) {
        let y = fy + ky as i64;
        if wyk == 0.0 || y < 0 || y >= h {
            continue;
        }
        for (kx, &wxk) in wx.iter().enumerate().take(nx) {
            let x = fx + kx as i64;
            if wxk == 0.0 || x < 0 || x >= w {
                continue;
            }
            put((x + y * w) as usize, wxk * wyk, x as usize, y as usize);
        }
    }
}

/// Accumulated sums over an axis-aligned pixel rectangle.
#[derive(Clone, Debug)]
pub struct FilmTile {
    pub x0: i64,
    pub y0: i64,
    pub width: usize,
    pub height: usize,
    filter: Filter,
    pub sum: Vec<[f64; 3]>,
    pub sum_sq: Vec<[f64; 3]>,
    pub weight: Vec<f64>,
    /// Σ w² per pixel.
    pub weight_sq: Vec<f64>,
    /// Σ w² f and Σ w² f² per pixel and channel, and Σ w³: for the variance of the
    /// weighted mean (see [`Film::sample_variance`]).
    pub sum_w2: Vec<[f64; 3]>,
    pub sum_sq_w2: Vec<[f64; 3]>,
    pub weight_cube: Vec<f64>,
    /// Samples added.
    pub samples: u64,
}

impl FilmTile {
    /// A tile covering pixels [x0, x0 + width) × [y0, y0 + height), enlarged by the filter's
    /// border on every side.
    pub fn new(x0: usize, y0: usize, width: usize, height: usize, filter: Filter) -> Self {
        Self::new_at(x0 as i64, y0 as i64, width, height, filter)
    }

    /// [`FilmTile::new`] at a corner that may lie outside the image (a tile of pixels sampled
    /// beyond its edges, Mitsuba's `sample_border`; only what reaches the image is merged).
    pub fn new_at(x0: i64, y0: i64, width: usize, height: usize, filter: Filter) -> Self {
        let b = filter.border();
        let (w, h) = (width + 2 * b, height + 2 * b);
        FilmTile {
            x0: x0 - b as i64,
            y0: y0 - b as i64,
            width: w,
            height: h,
            filter,
            sum: vec![[0.0; 3]; w * h],
            sum_sq: vec![[0.0; 3]; w * h],
            weight: vec![0.0; w * h],
            weight_sq: vec![0.0; w * h],
            sum_w2: vec![[0.0; 3]; w * h],
            sum_sq_w2: vec![[0.0; 3]; w * h],
            weight_cube: vec![0.0; w * h],
            samples: 0,
        }
    }

    #[inline]
    fn axis_weights(&self, pos: f64, r: f64, out: &mut [f64; 16]) -> (i64, usize) {
        axis_weights(self.filter, pos, r, out)
    }

    /// Adds a sample with value `v` at continuous film position `pos` (pixels; pixel (i, j)
    /// spans [i, i+1) × [j, j+1), its centre at (i + ½, j + ½)).
    #[inline]
    pub fn add_sample(&mut self, pos: Vec2, v: Vec3) {
        self.samples += 1;
        match self.filter {
            Filter::Box => {
                let x = pos.x.floor() as i64 - self.x0;
                let y = pos.y.floor() as i64 - self.y0;
                if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
                    self.add(x as usize + y as usize * self.width, v, 1.0);
                }
            }
            _ => {
                let r = self.filter.radius();
                let (mut wx, mut wy) = ([0.0; 16], [0.0; 16]);
                let (fx, nx) = self.axis_weights(pos.x as f64, r, &mut wx);
                let (fy, ny) = self.axis_weights(pos.y as f64, r, &mut wy);
                for (ky, &wyk) in wy.iter().enumerate().take(ny) {
                    let y = fy + ky as i64 - self.y0;
                    if wyk == 0.0 || y < 0 || y >= self.height as i64 {
                        continue;
                    }
                    for (kx, &wxk) in wx.iter().enumerate().take(nx) {
                        let x = fx + kx as i64 - self.x0;
                        if wxk == 0.0 || x < 0 || x >= self.width as i64 {
                            continue;
                        }
                        self.add(x as usize + y as usize * self.width, v, wxk * wyk);
                    }
                }
            }
        }
    }

    #[inline]
    fn add(&mut self, i: usize, v: Vec3, w: f64) {
        let w2 = w * w;
        for c in 0..3 {
            let x = v[c] as f64;
            self.sum[i][c] += w * x;
            self.sum_sq[i][c] += w * x * x;
            self.sum_w2[i][c] += w2 * x;
            self.sum_sq_w2[i][c] += w2 * x * x;
        }
        self.weight[i] += w;
        self.weight_sq[i] += w2;
        self.weight_cube[i] += w2 * w;
    }
}

/// The whole image's sums.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: usize,
    pub height: usize,
    pub filter: Filter,
    pub sum: Vec<[f64; 3]>,
    pub sum_sq: Vec<[f64; 3]>,
    pub weight: Vec<f64>,
    /// Σ w² per pixel.
    pub weight_sq: Vec<f64>,
    /// Σ w² f, Σ w² f² and Σ w³, as in [`FilmTile`].
    pub sum_w2: Vec<[f64; 3]>,
    pub sum_sq_w2: Vec<[f64; 3]>,
    pub weight_cube: Vec<f64>,
    /// Samples accumulated over the whole image.
    pub samples: u64,
}

impl Film {
    pub fn new(width: usize, height: usize, filter: Filter) -> Self {
        let n = width * height;
        Film {
            width,
            height,
            filter,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            weight: vec![0.0; n],
            weight_sq: vec![0.0; n],
            sum_w2: vec![[0.0; 3]; n],
            sum_sq_w2: vec![[0.0; 3]; n],
            weight_cube: vec![0.0; n],
            samples: 0,
        }
    }

    /// Adds a tile's sums (the parts inside the image).
    pub fn merge(&mut self, tile: &FilmTile) {
        self.samples += tile.samples;
        for ty in 0..tile.height {
            let y = tile.y0 + ty as i64;
            if y < 0 || y >= self.height as i64 {
                continue;
            }
            for tx in 0..tile.width {
                let x = tile.x0 + tx as i64;
                if x < 0 || x >= self.width as i64 {
                    continue;
                }
                let i = x as usize + y as usize * self.width;
                let j = tx + ty * tile.width;
                for c in 0..3 {
                    self.sum[i][c] += tile.sum[j][c];
                    self.sum_sq[i][c] += tile.sum_sq[j][c];
                    self.sum_w2[i][c] += tile.sum_w2[j][c];
                    self.sum_sq_w2[i][c] += tile.sum_sq_w2[j][c];
                }
                self.weight[i] += tile.weight[j];
                self.weight_sq[i] += tile.weight_sq[j];
                self.weight_cube[i] += tile.weight_cube[j];
            }
        }
    }

    /// Adds another film's sums (same size and filter): the film of a render continued from
    /// where this one stopped.
    pub fn add(&mut self, other: &Film) {
        self.samples += other.samples;
        for i in 0..self.sum.len().min(other.sum.len()) {
            for c in 0..3 {
                self.sum[i][c] += other.sum[i][c];
                self.sum_sq[i][c] += other.sum_sq[i][c];
                self.sum_w2[i][c] += other.sum_w2[i][c];
                self.sum_sq_w2[i][c] += other.sum_sq_w2[i][c];
            }
            self.weight[i] += other.weight[i];
            self.weight_sq[i] += other.weight_sq[i];
            self.weight_cube[i] += other.weight_cube[i];
        }
    }

    /// Adds one pass of a light tracer: `pass` holds, per pixel, the sum of the splats of
    /// `width · height` particles, which is one sample of that pixel (weight 1, as a
    /// box-filtered camera sample), so that the image, the per-pixel variance and the sample
    /// count mean what they mean for camera integrators.
    pub fn add_light_pass(&mut self, pass: &[[f64; 3]]) {
        self.samples += (self.width * self.height) as u64;
        for (i, v) in pass.iter().enumerate().take(self.sum.len()) {
            for (c, &x) in v.iter().enumerate() {
                self.sum[i][c] += x;
                self.sum_sq[i][c] += x * x;
                self.sum_w2[i][c] += x;
                self.sum_sq_w2[i][c] += x * x;
            }
            self.weight[i] += 1.0;
            self.weight_sq[i] += 1.0;
            self.weight_cube[i] += 1.0;
        }
    }

    /// Adds one pass of camera samples and splats ([`MixedPass`]): per pixel one sample of
    /// weight W = Σ w and value Σ w f / W + L (pixels no camera sample reached in this pass,
    /// W = 0, take nothing from it).
    pub fn add_mixed_pass(&mut self, pass: &MixedPass) {
        self.samples += (self.width * self.height) as u64;
        for i in 0..self.sum.len().min(pass.sum.len()) {
            let w = pass.weight[i];
            if w <= 0.0 {
                continue;
            }
            let (w2, w3) = (w * w, w * w * w);
            for c in 0..3 {
                let x = pass.sum[i][c] / w + pass.splat[i][c];
                self.sum[i][c] += w * x;
                self.sum_sq[i][c] += w * x * x;
                self.sum_w2[i][c] += w2 * x;
                self.sum_sq_w2[i][c] += w2 * x * x;
            }
            self.weight[i] += w;
            self.weight_sq[i] += w2;
            self.weight_cube[i] += w3;
        }
    }

    /// Spreads a light tracer's splat of value `v` at film position `pos` (pixels) over the
    /// pixels of `pass` (this film's size) with the reconstruction filter's weights
    /// normalised to sum to 1 over its footprint (Mitsuba's normalised `ImageBlock::put`);
    /// the parts that fall outside the image are lost.
    pub fn splat(&self, pass: &mut [[f64; 3]], pos: Vec2, v: Vec3) {
        let (w, h) = (self.width as i64, self.height as i64);
        let mut put = |x: i64, y: i64, wt: f64| {
            if x >= 0 && y >= 0 && x < w && y < h {
                let p = &mut pass[(x + y * w) as usize];
                for c in 0..3 {
                    p[c] += wt * v[c] as f64;
                }
            }
        };
        if self.filter == Filter::Box {
            put(pos.x.floor() as i64, pos.y.floor() as i64, 1.0);
            return;
        }
        let r = self.filter.radius();
        let axis = |p: f64| {
            let first = (p - 0.5 - r).floor() as i64 + 1;
            let last = (p - 0.5 + r).ceil() as i64 - 1;
            (first..=last).map(move |i| {
                let d = (i as f64 + 0.5 - p).abs();
                (i, if d < r { self.filter.eval(d) } else { 0.0 })
            })
        };
        let (px, py) = (pos.x as f64, pos.y as f64);
        let total: f64 =
            axis(px).map(|(_, w)| w).sum::<f64>() * axis(py).map(|(_, w)| w).sum::<f64>();
        if total <= 0.0 {
            return;
        }
        for (y, wy) in axis(py) {
            for (x, wx) in axis(px) {
                put(x, y, wx * wy / total);
            }
        }
    }

    /// The reconstructed image: weighted mean per pixel (0 where no weight landed).
    pub fn image(&self) -> Vec<[f32; 3]> {
        (0..self.sum.len())
            .map(|i| self.mean_f64(i).map(|m| m as f32))
            .collect()
    }

    /// Pixel `i`'s weighted mean in f64 (0 where no weight landed): [`Film::image`] before
    /// its rounding to f32, for computations that must not underflow or overflow f32.
    #[inline]
    pub fn mean_f64(&self, i: usize) -> [f64; 3] {
        let w = self.weight[i];
        if w > 0.0 {
            self.sum[i].map(|s| s / w)
        } else {
            [0.0; 3]
        }
    }

    /// Samples per pixel accumulated (total samples over the pixel count).
    pub fn spp(&self) -> f64 {
        self.samples as f64 / (self.width * self.height).max(1) as f64
    }

    /// Per-pixel, per-channel weighted variance of the samples that reached a pixel,
    /// Σw f² / Σw − (Σw f / Σw)²: the variance of one sample (E[x²] − E[x]², what Mitsuba's
    /// `moment` integrator yields with the box filter).
    pub fn weighted_variance(&self) -> Vec<[f32; 3]> {
        (0..self.sum.len())
            .map(|i| {
                let w = self.weight[i];
                if w > 0.0 {
                    std::array::from_fn(|c| {
                        let m = self.sum[i][c] / w;
                        (self.sum_sq[i][c] / w - m * m).max(0.0) as f32
                    })
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }

    /// Per-pixel, per-channel "per-sample-equivalent" variance: spp × Var(pixel value), so
    /// that dividing by spp gives the variance of the pixel value. With the box filter it is
    /// the unbiased variance of one sample, n/(n − 1) · (E[x²] − E[x]²).
    ///
    /// With splatting filters the pixel value is the ratio estimator I = Σw f / Σw, whose
    /// variance is estimated by the linearisation (delta-method) estimator of ratio
    /// estimators (Cochran 1977, "Sampling Techniques", §6.4), Σ w² (f − I)² / (Σw)²,
    /// computed from the sums Σw²f², Σw²f and Σw², and made unbiased for independent
    /// samples of common variance σ² (E[Σ w²(f − I)²] = σ² (Σw² − 2Σw³/Σw + (Σw²)²/(Σw)²),
    /// where the target is σ² Σw²/(Σw)²). This estimator weights each sample by w², so at
    /// edges it does not count the change of the image across the filter's footprint as
    /// noise. Measured on the gaussian-filtered Cornell box (128², 16 renders of 16 spp):
    /// the empirical variance of the pixel values over the predicted one is 0.995 summed
    /// over the 99% of pixel-channels with the smallest variance (0.74 over all: the rest
    /// are heavy-tailed pixels at the light's edge, where 256 samples underestimate); the
    /// simpler weighted variance × Σw²/(Σw)² gave 0.56 over all.
    pub fn sample_variance(&self) -> Vec<[f32; 3]> {
        let spp = self.spp();
        (0..self.sum.len())
            .map(|i| self.sample_variance_f64(i, spp).map(|v| v as f32))
            .collect()
    }

    /// Pixel `i`'s [`Film::sample_variance`] in f64, before its rounding to f32 (`spp` is
    /// [`Film::spp`]): a scene scaled by 2⁻⁶⁶ has variances near 2⁻¹³², below f32's range,
    /// and a scene scaled by 2⁵³ squares near 2¹⁰⁶; in f64 both scale exactly.
    #[inline]
    pub fn sample_variance_f64(&self, i: usize, spp: f64) -> [f64; 3] {
        let (w, w2, w3) = (self.weight[i], self.weight_sq[i], self.weight_cube[i]);
        if w <= 0.0 {
            return [0.0; 3];
        }
        let dof = w2 - 2.0 * w3 / w + w2 * w2 / (w * w);
        if dof <= 1e-12 * w2 {
            return [0.0; 3]; // a single sample: no estimate
        }
        std::array::from_fn(|c| {
            let m = self.sum[i][c] / w;
            let ss = self.sum_sq_w2[i][c] - 2.0 * m * self.sum_w2[i][c] + m * m * w2;
            spp * ss.max(0.0) / dof * w2 / (w * w)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_filter_accumulates_mean_and_variance() {
        let mut film = Film::new(4, 3, Filter::Box);
        let mut tile = FilmTile::new(2, 1, 2, 2, Filter::Box);
        tile.add_sample(Vec2::new(2.5, 1.5), Vec3::new(1.0, 2.0, 3.0));
        tile.add_sample(Vec2::new(2.99, 1.01), Vec3::new(3.0, 2.0, 1.0));
        tile.add_sample(Vec2::new(3.0, 2.0), Vec3::splat(7.0));
        film.merge(&tile);
        let img = film.image();
        assert_eq!(img[2 + 4], [2.0, 2.0, 2.0]);
        assert_eq!(img[3 + 2 * 4], [7.0; 3]);
        assert_eq!(img[0], [0.0; 3]);
        let var = film.weighted_variance();
        assert_eq!(var[2 + 4], [1.0, 0.0, 1.0]);
    }

    /// A light tracer's splat lands on each pixel with the filter's weight at the pixel
    /// centre in x times that in y, over the sum of all such products: the tent's weights
    /// written out here from its definition, 1 − |d| / r.
    #[test]
    fn splat_spreads_with_normalised_separable_weights() {
        let r = 1.5;
        let film = Film::new(12, 10, Filter::Tent { radius: r });
        let mut pass = vec![[0.0; 3]; 12 * 10];
        let (px, py) = (5.3f64, 4.8f64);
        film.splat(
            &mut pass,
            Vec2::new(px as f32, py as f32),
            Vec3::new(1.0, 2.0, 3.0),
        );
        let tent = |i: usize, p: f64| (1.0 - ((i as f64 + 0.5) - p).abs() / r).max(0.0);
        let (sx, sy): (f64, f64) = (
            (0..12).map(|i| tent(i, px)).sum(),
            (0..10).map(|i| tent(i, py)).sum(),
        );
        let mut total = 0.0;
        for y in 0..10 {
            for x in 0..12 {
                let want = tent(x, px) * tent(y, py) / (sx * sy);
                let got = pass[x + 12 * y];
                for (c, k) in [1.0, 2.0, 3.0].iter().enumerate() {
                    assert!(
                        (got[c] - k * want).abs() <= 1e-6 * k,
                        "({x}, {y}) {got:?} {want}"
                    );
                }
                total += got[0];
            }
        }
        assert!((total - 1.0).abs() < 1e-6, "{total}");
        // Three pixels per axis are reached (|d| < 1.5): a real spread, not one pixel.
        assert_eq!(pass.iter().filter(|p| p[0] > 0.0).count(), 9);
    }

    /// Samples scattered over an 8 × 6 image and added tile by tile (3 × 2 tiles, each
    /// enlarged by the filter's border) give every pixel the weight Σ w(dx) w(dy) over the
    /// samples within the filter's radius on both axes: the sum written out from the filter's
    /// definition, one pixel at a time. A tile that drops a row or column of its border, or
    /// a weight outside the radius, shows here.
    #[test]
    fn tiles_give_each_pixel_every_filter_weight_within_the_radius() {
        let (w, h) = (8usize, 6usize);
        let mut rng = crate::sampler::SampleStream::new(0xf11, 0, 0);
        let points: Vec<Vec2> = (0..600)
            .map(|_| rng.next_2d() * Vec2::new(w as f32, h as f32))
            .collect();
        for filter in [
            Filter::Gaussian { stddev: 0.5 },
            Filter::Tent { radius: 1.0 },
            Filter::Tent { radius: 1.7 },
        ] {
            let mut film = Film::new(w, h, filter);
            for ty in (0..h).step_by(2) {
                for tx in (0..w).step_by(3) {
                    let (tw, th) = (3.min(w - tx), 2.min(h - ty));
                    let mut tile = FilmTile::new(tx, ty, tw, th, filter);
                    for p in &points {
                        let (px, py) = (p.x as usize, p.y as usize);
                        if (tx..tx + tw).contains(&px) && (ty..ty + th).contains(&py) {
                            tile.add_sample(*p, Vec3::new(1.0, 2.0, 3.0));
                        }
                    }
                    film.merge(&tile);
                }
            }
            assert_eq!(film.samples, points.len() as u64);
            let r = filter.radius();
            let weight_1d = |d: f64| if d.abs() < r { filter.eval(d) } else { 0.0 };
            for y in 0..h {
                for x in 0..w {
                    let expected: f64 = points
                        .iter()
                        .map(|p| {
                            weight_1d(x as f64 + 0.5 - p.x as f64)
                                * weight_1d(y as f64 + 0.5 - p.y as f64)
                        })
                        .sum();
                    let i = x + y * w;
                    assert!(expected > 0.0);
                    assert!(
                        (film.weight[i] - expected).abs() <= 1e-12 * expected,
                        "{filter:?} pixel ({x}, {y}): weight {} expected {expected}",
                        film.weight[i]
                    );
                    assert!((film.sum[i][2] - 3.0 * expected).abs() <= 1e-12 * expected);
                }
            }
        }
    }

    /// `Film::add` (a render continued where another stopped) sums the sample counts and
    /// every per-pixel sum.
    #[test]
    fn adding_films_sums_their_samples_and_sums() {
        let filter = Filter::Tent { radius: 1.0 };
        let film_of = |points: &[(f32, f32, f32)]| {
            let mut tile = FilmTile::new(0, 0, 2, 2, filter);
            for &(x, y, v) in points {
                tile.add_sample(Vec2::new(x, y), Vec3::splat(v));
            }
            let mut film = Film::new(2, 2, filter);
            film.merge(&tile);
            film
        };
        let a = [(0.5, 0.5, 1.0), (1.2, 0.7, 2.0), (1.9, 1.9, 4.0)];
        let b = [(0.1, 1.5, 8.0), (1.5, 1.5, 16.0)];
        let mut sum = film_of(&a);
        sum.add(&film_of(&b));
        let all = film_of(&[a.as_slice(), b.as_slice()].concat());
        assert_eq!(sum.samples, 5);
        assert_eq!(sum.spp(), 5.0 / 4.0);
        for i in 0..4 {
            assert!((sum.weight[i] - all.weight[i]).abs() < 1e-12);
            assert!((sum.weight_sq[i] - all.weight_sq[i]).abs() < 1e-12);
            assert!((sum.weight_cube[i] - all.weight_cube[i]).abs() < 1e-12);
            for c in 0..3 {
                assert!((sum.sum[i][c] - all.sum[i][c]).abs() < 1e-9);
                assert!((sum.sum_sq[i][c] - all.sum_sq[i][c]).abs() < 1e-9);
                assert!((sum.sum_w2[i][c] - all.sum_w2[i][c]).abs() < 1e-9);
                assert!((sum.sum_sq_w2[i][c] - all.sum_sq_w2[i][c]).abs() < 1e-9);
            }
        }
    }

    /// Splats spread uniformly over the region camera samples are drawn from (the image and
    /// the sample border beyond it), 1 per unit of film area, give every pixel of a mixed
    /// pass the value 1, at the edges and corners too: each splat reaches pixel c with
    /// w(x − c) / ∫ w(y − c) dy over that region. (A midpoint rule of 32 x 32 splats per
    /// pixel: exact to ~1e-4.) Normalised by each splat's own footprint instead
    /// ([`Film::splat`]), the corner pixel of a gaussian filter gets ~0.7.
    #[test]
    fn mixed_pass_splats_are_normalised_per_pixel() {
        let (w, h) = (6usize, 5usize);
        for (filter, border) in [
            (Filter::Gaussian { stddev: 0.5 }, 0usize),
            (Filter::Tent { radius: 1.5 }, 0),
            (Filter::Gaussian { stddev: 1.0 }, 2),
            (Filter::Box, 0),
        ] {
            let mut pass = MixedPass::new(w, h, filter, border);
            let mut footprint = vec![[0.0f64; 3]; w * h];
            let film = Film::new(w, h, filter);
            let k = 32;
            let b = border as i64;
            for py in -b..h as i64 + b {
                for px in -b..w as i64 + b {
                    for j in 0..k * k {
                        let pos = Vec2::new(
                            px as f32 + ((j % k) as f32 + 0.5) / k as f32,
                            py as f32 + ((j / k) as f32 + 0.5) / k as f32,
                        );
                        let v = Vec3::splat(1.0 / (k * k) as f32);
                        pass.add_splat(pos, v);
                        film.splat(&mut footprint, pos, v);
                    }
                }
            }
            // One black camera sample per pixel, at its centre: every pixel has weight.
            for y in 0..h {
                for x in 0..w {
                    pass.add_sample(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), Vec3::ZERO);
                }
            }
            let mut out = Film::new(w, h, filter);
            out.add_mixed_pass(&pass);
            assert_eq!(out.samples, (w * h) as u64);
            for (i, p) in out.image().iter().enumerate() {
                for v in p {
                    assert!((v - 1.0).abs() < 1e-3, "{filter:?} pixel {i}: {v}");
                }
            }
            if filter == (Filter::Gaussian { stddev: 0.5 }) {
                assert!(footprint[0][0] < 0.75, "corner {}", footprint[0][0]);
            }
        }
    }

    /// A mixed pass's camera samples make Mitsuba's ratio estimator: Σ w f / Σ w per pixel,
    /// with the splats' value added (one sample of weight Σ w per pixel per pass).
    #[test]
    fn mixed_pass_camera_samples_are_the_filtered_mean() {
        let filter = Filter::Tent { radius: 1.0 };
        let mut pass = MixedPass::new(3, 2, filter, 0);
        let samples = [
            (0.3, 0.4, 1.0),
            (0.9, 0.6, 3.0),
            (1.2, 0.2, 5.0),
            (2.5, 1.5, 7.0),
        ];
        for &(x, y, v) in &samples {
            pass.add_sample(Vec2::new(x, y), Vec3::splat(v));
        }
        pass.add_splat(Vec2::new(0.5, 0.5), Vec3::splat(2.0));
        let mut film = Film::new(3, 2, filter);
        film.add_mixed_pass(&pass);
        let tent = |d: f64| (1.0 - d.abs()).max(0.0);
        // Pixel (0, 0): the tent's weights at its centre (0.5, 0.5).
        let (mut sw, mut swf) = (0.0, 0.0);
        for &(x, y, v) in &samples {
            let wt = tent(x as f64 - 0.5) * tent(y as f64 - 0.5);
            sw += wt;
            swf += wt * v as f64;
        }
        // The splat at the centre: weight 1 over ∫ tent = (1 − 1/8)² at this corner.
        let want = swf / sw + 2.0 / (0.875 * 0.875);
        let got = film.image()[0][0] as f64;
        assert!((got - want).abs() < 1e-5 * want, "{got} vs {want}");
        assert!((film.weight[0] - sw).abs() < 1e-12);
    }

    #[test]
    fn constant_sum_of_many_samples_is_exact() {
        // 2^20 samples of one f32 value: the f64 mean returns the value bit for bit.
        let v = 0.1f32;
        let mut tile = FilmTile::new(0, 0, 1, 1, Filter::Box);
        for _ in 0..(1 << 20) {
            tile.add_sample(Vec2::new(0.5, 0.5), Vec3::splat(v));
        }
        let mut film = Film::new(1, 1, Filter::Box);
        film.merge(&tile);
        assert_eq!(film.image()[0], [v; 3]);
    }
}
