//! Mitsuba's `hdrfilm` accumulation, in f64: per pixel the weighted sum of sample values, of
//! their squares (for the per-pixel variance) and of the filter weights. Samples are placed
//! uniformly in their pixel and splatted to the pixels within the reconstruction filter's
//! radius; the weights are divided out at the end. Each render tile accumulates into its own
//! [`FilmTile`] (its pixels plus a border of the filter radius), and tiles are merged in a
//! fixed order, so the sums are bit-identical whatever the thread count.

use glam::{Vec2, Vec3};

/// Reconstruction filters (Mitsuba's `rfilter`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// Mitsuba's `box` with its default radius 0.5: each sample counts for the pixel it falls
    /// in, with weight 1.
    Box,
}

impl Filter {
    /// How many pixels beyond its own a sample can reach.
    pub fn border(&self) -> usize {
        match self {
            Filter::Box => 0,
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
}

impl FilmTile {
    /// A tile covering pixels [x0, x0 + width) × [y0, y0 + height), enlarged by the filter's
    /// border on every side.
    pub fn new(x0: usize, y0: usize, width: usize, height: usize, filter: Filter) -> Self {
        let b = filter.border();
        let (w, h) = (width + 2 * b, height + 2 * b);
        FilmTile {
            x0: x0 as i64 - b as i64,
            y0: y0 as i64 - b as i64,
            width: w,
            height: h,
            filter,
            sum: vec![[0.0; 3]; w * h],
            sum_sq: vec![[0.0; 3]; w * h],
            weight: vec![0.0; w * h],
        }
    }

    /// Adds a sample with value `v` at continuous film position `pos` (pixels; pixel (i, j)
    /// spans [i, i+1) × [j, j+1)).
    #[inline]
    pub fn add_sample(&mut self, pos: Vec2, v: Vec3) {
        match self.filter {
            Filter::Box => {
                let x = pos.x.floor() as i64 - self.x0;
                let y = pos.y.floor() as i64 - self.y0;
                if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
                    self.add(x as usize + y as usize * self.width, v, 1.0);
                }
            }
        }
    }

    #[inline]
    fn add(&mut self, i: usize, v: Vec3, w: f64) {
        let s = &mut self.sum[i];
        let q = &mut self.sum_sq[i];
        for c in 0..3 {
            let x = v[c] as f64;
            s[c] += w * x;
            q[c] += w * x * x;
        }
        self.weight[i] += w;
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
        }
    }

    /// Adds a tile's sums (the parts inside the image).
    pub fn merge(&mut self, tile: &FilmTile) {
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
                }
                self.weight[i] += tile.weight[j];
            }
        }
    }

    /// Adds another film's sums (same size and filter): the film of a render continued from
    /// where this one stopped.
    pub fn add(&mut self, other: &Film) {
        for i in 0..self.sum.len().min(other.sum.len()) {
            for c in 0..3 {
                self.sum[i][c] += other.sum[i][c];
                self.sum_sq[i][c] += other.sum_sq[i][c];
            }
            self.weight[i] += other.weight[i];
        }
    }

    /// The reconstructed image: weighted mean per pixel (0 where no weight landed).
    pub fn image(&self) -> Vec<[f32; 3]> {
        (0..self.sum.len())
            .map(|i| {
                let w = self.weight[i];
                if w > 0.0 {
                    self.sum[i].map(|s| (s / w) as f32)
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }

    /// Per-pixel, per-channel variance of one sample, E[x²] − E[x]² (what Mitsuba's `moment`
    /// integrator yields); divide by the sample count for the variance of the pixel mean.
    pub fn sample_variance(&self) -> Vec<[f32; 3]> {
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
        let var = film.sample_variance();
        assert_eq!(var[2 + 4], [1.0, 0.0, 1.0]);
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
