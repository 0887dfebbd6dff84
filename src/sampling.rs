//! Shared sampling math: warps from the unit square and the MIS heuristic. Everything that
//! samples a direction or a point uses these; nothing re-implements them.

use crate::simd::{LaneF32, Lanes, Scalar, V3};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// Shirley and Chiu 1997, "A Low Distortion Map Between Disk and Square": the concentric map
/// from [0,1)² to the unit disk. The width-1 instance of
/// [`square_to_uniform_disk_concentric_lanes`].
#[inline]
pub fn square_to_uniform_disk_concentric(u: Vec2) -> Vec2 {
    let (x, y) = square_to_uniform_disk_concentric_lanes(Scalar, (u.x, u.y));
    Vec2::new(x, y)
}

/// [`square_to_uniform_disk_concentric`] in lanes: (x, y) of the disk point.
#[inline(always)]
pub fn square_to_uniform_disk_concentric_lanes<L: Lanes>(l: L, u: (L::F, L::F)) -> (L::F, L::F) {
    let (zero, one, two) = (l.splat(0.0), l.splat(1.0), l.splat(2.0));
    let ox = two * u.0 - one;
    let oy = two * u.1 - one;
    let centre = ox.cmp_eq(zero) & oy.cmp_eq(zero);
    let wide = ox.abs().cmp_gt(oy.abs());
    let r = L::F::select(wide, ox, oy);
    let theta = L::F::select(
        wide,
        l.splat(FRAC_PI_4) * (oy / ox),
        l.splat(FRAC_PI_2) - l.splat(FRAC_PI_4) * (ox / oy),
    );
    let (sin, cos) = l.sin_cos(theta);
    (
        L::F::select(centre, zero, r * cos),
        L::F::select(centre, zero, r * sin),
    )
}

/// Cosine-weighted hemisphere around +z by Malley's method (project the concentric disk).
/// The width-1 instance of [`square_to_cosine_hemisphere_lanes`].
#[inline]
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3 {
    square_to_cosine_hemisphere_lanes(Scalar, (u.x, u.y)).lane(0)
}

/// [`square_to_cosine_hemisphere`] in lanes.
#[inline(always)]
pub fn square_to_cosine_hemisphere_lanes<L: Lanes>(l: L, u: (L::F, L::F)) -> V3<L::F> {
    let (x, y) = square_to_uniform_disk_concentric_lanes(l, u);
    let z = (l.splat(1.0) - (x * x + y * y)).max(l.splat(0.0)).sqrt();
    V3::new(x, y, z)
}

/// Density of [`square_to_cosine_hemisphere`] w.r.t. solid angle.
#[inline]
pub fn square_to_cosine_hemisphere_pdf(v: Vec3) -> f32 {
    square_to_cosine_hemisphere_pdf_lanes(Scalar, v.z)
}

/// [`square_to_cosine_hemisphere_pdf`] in lanes, of the directions' z.
#[inline(always)]
pub fn square_to_cosine_hemisphere_pdf_lanes<L: Lanes>(l: L, z: L::F) -> L::F {
    L::F::select(z.cmp_gt(l.splat(0.0)), z / l.splat(PI), l.splat(0.0))
}

/// Uniform direction on the unit sphere.
#[inline]
pub fn square_to_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.y;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin, cos) = crate::math::sin_cosf(2.0 * PI * u.x);
    Vec3::new(r * cos, r * sin, z)
}

/// Uniform barycentrics (b1, b2) on a triangle (Shirley's square-root parameterisation);
/// b0 = 1 − b1 − b2.
#[inline]
pub fn square_to_uniform_triangle(u: Vec2) -> Vec2 {
    let (b1, b2) = square_to_uniform_triangle_lanes(Scalar, u.x, u.y);
    Vec2::new(b1, b2)
}

/// [`square_to_uniform_triangle`] lane by lane: (1 − t, u_y t) with t = √(1 − u_x).
#[inline(always)]
pub fn square_to_uniform_triangle_lanes<L: Lanes>(l: L, ux: L::F, uy: L::F) -> (L::F, L::F) {
    let one = l.splat(1.0);
    let t = (one - ux).sqrt();
    (one - t, uy * t)
}

/// Veach 1997 (thesis §9.2) power heuristic with β = 2, for one sample from each strategy.
/// The width-1 instance of [`mis_power_lanes`].
#[inline]
pub fn mis_power(pdf_a: f32, pdf_b: f32) -> f32 {
    mis_power_lanes(Scalar, pdf_a, pdf_b)
}

/// [`mis_power`] lane by lane: a² / (a² + b²) where that sum is positive and a² finite, else
/// 1 where a² is infinite, else 0.
#[inline(always)]
pub fn mis_power_lanes<L: Lanes>(l: L, pdf_a: L::F, pdf_b: L::F) -> L::F {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    let sum = a + b;
    let finite = a.is_finite();
    let ok = sum.cmp_gt(l.splat(0.0)) & finite;
    let infinite = !(finite | a.is_nan());
    L::F::select(
        ok,
        a / sum,
        L::F::select(infinite, l.splat(1.0), l.splat(0.0)),
    )
}

/// A discrete distribution over weights, sampled by inverting its CDF.
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    cdf: Vec<f64>,
    total: f64,
}

impl Distribution1D {
    /// `None` when no weight is positive or a weight is not finite.
    pub fn new(weights: impl IntoIterator<Item = f64>) -> Option<Self> {
        let mut cdf = Vec::new();
        let mut acc = 0.0;
        for w in weights {
            if !(w.is_finite() && w >= 0.0) {
                return None;
            }
            acc += w;
            cdf.push(acc);
        }
        (acc > 0.0).then_some(Distribution1D { cdf, total: acc })
    }

    pub fn total(&self) -> f64 {
        self.total
    }

    pub fn len(&self) -> usize {
        self.cdf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cdf.is_empty()
    }

    /// The probability of index `i`.
    pub fn pmf(&self, i: usize) -> f64 {
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (self.cdf[i] - lo) / self.total
    }

    /// Picks an index with probability ∝ weight and returns it with `u` rescaled to [0,1)
    /// within the chosen interval, so one random number serves twice.
    pub fn sample_reuse(&self, u: f32) -> (usize, f32) {
        let x = u as f64 * self.total;
        let i = self
            .cdf
            .partition_point(|&c| c <= x)
            .min(self.cdf.len() - 1);
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let w = self.cdf[i] - lo;
        let r = if w > 0.0 { ((x - lo) / w) as f32 } else { 0.0 };
        (i, r.clamp(0.0, 1.0 - f32::EPSILON / 2.0))
    }
}

/// Uniform direction in the cone of half-angle θmax around +z, given cos θmax.
#[inline]
pub fn square_to_uniform_cone(u: Vec2, cos_theta_max: f32) -> Vec3 {
    let cos_theta = (1.0 - u.y) + u.y * cos_theta_max;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sin_phi, cos_phi) = crate::math::sin_cosf(2.0 * PI * u.x);
    Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
}

/// Walker's alias method (Walker 1977) with Vose's numerically stable construction (Vose
/// 1991, "A linear algorithm for generating random numbers with a given distribution"):
/// O(1) sampling of a discrete distribution.
#[derive(Clone, Debug, Default)]
pub struct AliasTable {
    /// Probability of keeping bin i (else its alias).
    keep: Vec<f64>,
    alias: Vec<u32>,
    pmf: Vec<f64>,
}

impl AliasTable {
    /// `None` when no weight is positive or a weight is negative or not finite.
    pub fn new(weights: &[f64]) -> Option<Self> {
        let total: f64 = weights.iter().sum();
        if weights.is_empty()
            || !(total > 0.0 && total.is_finite())
            || weights.iter().any(|w| !(w.is_finite() && *w >= 0.0))
        {
            return None;
        }
        let n = weights.len();
        let pmf: Vec<f64> = weights.iter().map(|w| w / total).collect();
        let mut scaled: Vec<f64> = pmf.iter().map(|p| p * n as f64).collect();
        let mut keep = vec![1.0; n];
        let mut alias: Vec<u32> = (0..n as u32).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            keep[s] = scaled[s];
            alias[s] = l as u32;
            scaled[l] = (scaled[l] + scaled[s]) - 1.0;
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // What is left (rounding) keeps itself with probability 1.
        for i in small.into_iter().chain(large) {
            keep[i] = 1.0;
        }
        Some(AliasTable { keep, alias, pmf })
    }

    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// The probability of index `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f64 {
        self.pmf[i]
    }

    /// Picks an index and returns it with `u` remapped to [0, 1) for reuse.
    #[inline]
    pub fn sample_reuse(&self, u: f32) -> (usize, f32) {
        let n = self.pmf.len();
        let x = u as f64 * n as f64;
        let i = (x as usize).min(n - 1);
        let frac = (x - i as f64).clamp(0.0, 1.0);
        let q = self.keep[i];
        let (idx, r) = if frac < q {
            (i, frac / q)
        } else {
            (self.alias[i] as usize, (frac - q) / (1.0 - q))
        };
        (idx, (r as f32).clamp(0.0, 1.0 - f32::EPSILON / 2.0))
    }
}

/// A piecewise-constant density on [0,1]² over an nu × nv grid of cells (pbrt's
/// `PiecewiseConstant2D`, sampled as a marginal over rows and a conditional within the row).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    nu: usize,
    nv: usize,
    /// One per row; `None` for rows whose weights are all zero.
    conditional: Vec<Option<Distribution1D>>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// `weights[v * nu + u]`; `None` if no weight is positive or any is invalid.
    pub fn new(weights: &[f64], nu: usize, nv: usize) -> Option<Self> {
        if nu == 0 || nv == 0 || weights.len() != nu * nv {
            return None;
        }
        if weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return None;
        }
        let conditional: Vec<Option<Distribution1D>> = weights
            .chunks(nu)
            .map(|row| Distribution1D::new(row.iter().copied()))
            .collect();
        let marginal = Distribution1D::new(
            conditional
                .iter()
                .map(|c| c.as_ref().map_or(0.0, |d| d.total())),
        )?;
        Some(Distribution2D {
            nu,
            nv,
            conditional,
            marginal,
        })
    }

    /// A cell (i, j) with probability proportional to its weight, and the sample reused
    /// within it (uniform in [0,1)²); `None` only if a zero-weight row came up (never for
    /// a valid distribution).
    pub fn sample_cell(&self, u: Vec2) -> Option<(usize, usize, Vec2)> {
        let (j, fy) = self.marginal.sample_reuse(u.y);
        let (i, fx) = self.conditional[j].as_ref()?.sample_reuse(u.x);
        Some((i, j, Vec2::new(fx, fy)))
    }

    /// The probability of cell (i, j) (0 outside the grid).
    pub fn pmf(&self, i: usize, j: usize) -> f64 {
        if i >= self.nu || j >= self.nv {
            return 0.0;
        }
        match &self.conditional[j] {
            Some(row) => self.marginal.pmf(j) * row.pmf(i),
            None => 0.0,
        }
    }

    /// A continuous point in [0,1)² and its density w.r.t. area on [0,1]².
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let Some((i, j, Vec2 { x: fx, y: fy })) = self.sample_cell(u) else {
            return (Vec2::ZERO, 0.0);
        };
        let p = self.pmf(i, j) * (self.nu * self.nv) as f64;
        let uv = Vec2::new(
            ((i as f32 + fx) / self.nu as f32).min(1.0 - f32::EPSILON / 2.0),
            ((j as f32 + fy) / self.nv as f32).min(1.0 - f32::EPSILON / 2.0),
        );
        (uv, p as f32)
    }

    /// The density at `uv` ∈ [0,1]².
    pub fn pdf(&self, uv: Vec2) -> f32 {
        let i = ((uv.x * self.nu as f32) as usize).min(self.nu - 1);
        let j = ((uv.y * self.nv as f32) as usize).min(self.nv - 1);
        (self.pmf(i, j) * (self.nu * self.nv) as f64) as f32
    }

    /// Sampling a tent on [−1, 1] (density 1 − |x|) from u ∈ [0, 1).
    pub fn square_to_tent(u: f32) -> f32 {
        if u < 0.5 {
            (2.0 * u).sqrt() - 1.0
        } else {
            1.0 - (2.0 - 2.0 * u).max(0.0).sqrt()
        }
    }
}

/// A density on [0,1]² that is bilinear between values on a grid of (nu + 1) × (nv + 1)
/// vertices, vertex (i, j) at (i / nu, j / nv): the density of Mitsuba's `warp::Marginal2D`
/// without parameters, what its `envmap` samples by. Sampled as a marginal in v (piecewise
/// linear between the rows' integrals) and a conditional in u at the sampled v (piecewise
/// linear between the two neighbouring rows' values interpolated), each linear piece
/// inverted in closed form.
#[derive(Clone, Debug)]
pub struct Bilinear2D {
    nu: usize,
    nv: usize,
    /// Vertex values, `f[j * (nu + 1) + i]`.
    f: Vec<f64>,
    /// Per vertex row j, the running integral over u in cell units:
    /// `row_cdf[j * (nu + 1) + i]` = Σ_{k<i} (f(k, j) + f(k + 1, j)) / 2.
    row_cdf: Vec<f64>,
    /// The running integral over v of the rows' integrals, in uv units: `marginal[j]` =
    /// ∫₀^{j/nv} ∫₀¹ f du dv; `marginal[nv]` is the total.
    marginal: Vec<f64>,
}

impl Bilinear2D {
    /// `values[j * (nu + 1) + i]` at the vertices; `None` if no value is positive or any is
    /// negative or not finite.
    pub fn new(values: &[f64], nu: usize, nv: usize) -> Option<Self> {
        let n = nu.checked_add(1)?.checked_mul(nv.checked_add(1)?)?;
        if nu == 0 || nv == 0 || values.len() != n {
            return None;
        }
        if values.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return None;
        }
        let mut row_cdf = Vec::with_capacity(n);
        for row in values.chunks(nu + 1) {
            let mut acc = 0.0;
            row_cdf.push(0.0);
            for k in 0..nu {
                acc += 0.5 * (row[k] + row[k + 1]);
                row_cdf.push(acc);
            }
        }
        let row_integral = |j: usize| row_cdf[j * (nu + 1) + nu] / nu as f64;
        let mut marginal = Vec::with_capacity(nv + 1);
        let mut acc = 0.0;
        marginal.push(0.0);
        for j in 0..nv {
            acc += 0.5 * (row_integral(j) + row_integral(j + 1)) / nv as f64;
            marginal.push(acc);
        }
        (acc > 0.0 && acc.is_finite()).then(|| Bilinear2D {
            nu,
            nv,
            f: values.to_vec(),
            row_cdf,
            marginal,
        })
    }

    /// The t in [0, 1] where ∫₀ᵗ (a + (b − a) s) ds = r, for a, b ≥ 0 (the inverse of a
    /// linear piece's integral, in the form that stays exact as b − a → 0).
    fn invert_linear(a: f64, b: f64, r: f64) -> f64 {
        let r = r.max(0.0);
        let d = a * a + 2.0 * (b - a) * r;
        let den = a + d.max(0.0).sqrt();
        if den > 0.0 {
            (2.0 * r / den).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The bilinear value in cell (i, j) at (s, t) ∈ [0, 1]².
    fn value(&self, i: usize, j: usize, s: f64, t: f64) -> f64 {
        let w = self.nu + 1;
        let at = |i: usize, j: usize| self.f[j * w + i];
        let lo = at(i, j) + (at(i + 1, j) - at(i, j)) * s;
        let hi = at(i, j + 1) + (at(i + 1, j + 1) - at(i, j + 1)) * s;
        lo + (hi - lo) * t
    }

    /// A point in [0,1]² drawn from the density, and its density there.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (nu, nv, w) = (self.nu, self.nv, self.nu + 1);
        let total = self.marginal[nv];
        // v: the row cell by the marginal, then the linear piece within it.
        let target = u.y as f64 * total;
        let j = (self.marginal.partition_point(|&m| m <= target).max(1) - 1).min(nv - 1);
        let row_integral = |j: usize| self.row_cdf[j * w + nu] / nu as f64;
        let (a, b) = (row_integral(j), row_integral(j + 1));
        let t = Self::invert_linear(a, b, (target - self.marginal[j]) * nv as f64);
        // u: the conditional at that v, the rows' running integrals interpolated.
        let cdf = |i: usize| {
            let (c0, c1) = (self.row_cdf[j * w + i], self.row_cdf[(j + 1) * w + i]);
            c0 + (c1 - c0) * t
        };
        let target = u.x as f64 * cdf(nu);
        let (mut lo, mut hi) = (0usize, nu);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if cdf(mid) <= target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let i = lo;
        let g = |i: usize| {
            let (f0, f1) = (self.f[j * w + i], self.f[(j + 1) * w + i]);
            f0 + (f1 - f0) * t
        };
        let s = Self::invert_linear(g(i), g(i + 1), target - cdf(i));
        let uv = Vec2::new(
            (((i as f64 + s) / nu as f64) as f32).min(1.0 - f32::EPSILON / 2.0),
            (((j as f64 + t) / nv as f64) as f32).min(1.0 - f32::EPSILON / 2.0),
        );
        (uv, (self.value(i, j, s, t) / total) as f32)
    }

    /// The density at `uv` ∈ [0,1]².
    pub fn pdf(&self, uv: Vec2) -> f32 {
        let x = (uv.x as f64).clamp(0.0, 1.0) * self.nu as f64;
        let y = (uv.y as f64).clamp(0.0, 1.0) * self.nv as f64;
        let i = (x as usize).min(self.nu - 1);
        let j = (y as usize).min(self.nv - 1);
        (self.value(i, j, x - i as f64, y - j as f64) / self.marginal[self.nv]) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Distribution2D::sample` keeps its promise of a point in [0,1)² at the largest
    /// random numbers, where (j + fy) / nv rounds to 1 in f32 without the clamp (an
    /// environment map would then sample the pole, sin θ = 0, and lose the sample).
    #[test]
    fn distribution2d_sample_stays_below_one() {
        let below_one = 1.0 - f32::EPSILON / 2.0;
        for (nu, nv) in [(1, 3), (3, 1), (7, 5), (64, 32)] {
            let weights: Vec<f64> = (0..nu * nv).map(|k| 1.0 + k as f64).collect();
            let d = Distribution2D::new(&weights, nu, nv).unwrap();
            for u in [
                Vec2::ZERO,
                Vec2::splat(below_one),
                Vec2::new(0.5, below_one),
            ] {
                let (uv, pdf) = d.sample(u);
                assert!(
                    (0.0..1.0).contains(&uv.x) && (0.0..1.0).contains(&uv.y) && pdf > 0.0,
                    "{nu}x{nv} at {u}: {uv} (pdf {pdf})"
                );
                assert_eq!(d.pdf(uv), pdf);
            }
        }
    }

    #[test]
    fn concentric_disk_stays_in_disk_and_maps_corners() {
        for i in 0..=20 {
            for j in 0..=20 {
                let d = square_to_uniform_disk_concentric(Vec2::new(i as f32, j as f32) / 20.0);
                assert!(d.length() <= 1.0 + 1e-6);
            }
        }
        let c = square_to_uniform_disk_concentric(Vec2::new(1.0, 0.5));
        assert!((c - Vec2::X).length() < 1e-6);
    }

    #[test]
    fn cosine_hemisphere_has_expected_mean_cos() {
        // E[cos θ] under p = cos/π is 2/3; a 64x64 stratified grid gets it to ~1e-3.
        let n = 64;
        let mut acc = 0.0;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                acc += square_to_cosine_hemisphere(u).z as f64;
            }
        }
        assert!((acc / (n * n) as f64 - 2.0 / 3.0).abs() < 2e-3);
    }

    #[test]
    fn triangle_barycentrics_are_valid() {
        for (x, y) in [(0.0, 0.0), (0.999, 0.999), (0.5, 0.2)] {
            let b = square_to_uniform_triangle(Vec2::new(x, y));
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
        }
    }

    #[test]
    fn power_heuristic_is_a_partition_of_unity() {
        assert!((mis_power(0.3, 0.7) + mis_power(0.7, 0.3) - 1.0).abs() < 1e-6);
        assert_eq!(mis_power(0.0, 0.0), 0.0);
        assert_eq!(mis_power(f32::INFINITY, 1.0), 1.0);
    }

    #[test]
    fn distribution_samples_proportionally() {
        let d = Distribution1D::new([1.0, 0.0, 3.0]).unwrap();
        assert_eq!(d.sample_reuse(0.1).0, 0);
        assert_eq!(d.sample_reuse(0.3).0, 2);
        assert!((d.pmf(2) - 0.75).abs() < 1e-12);
        assert_eq!(d.pmf(1), 0.0);
        let (i, r) = d.sample_reuse(0.625);
        assert_eq!(i, 2);
        assert!((r - 0.5).abs() < 1e-6);
        assert!(Distribution1D::new([0.0, 0.0]).is_none());
        assert!(Distribution1D::new([f64::NAN]).is_none());
    }

    #[test]
    fn alias_table_matches_weights() {
        let w = [1.0, 0.0, 3.0, 0.5, 5.5];
        let t = AliasTable::new(&w).unwrap();
        // Integrate the sampled index over a fine uniform grid: exact frequencies.
        let n = 100_000;
        let mut counts = [0usize; 5];
        for k in 0..n {
            let (i, r) = t.sample_reuse((k as f32 + 0.5) / n as f32);
            assert!((0.0..1.0).contains(&r));
            counts[i] += 1;
        }
        for i in 0..5 {
            assert!(
                (counts[i] as f64 / n as f64 - w[i] / 10.0).abs() < 1e-3,
                "{counts:?}"
            );
            assert!((t.pmf(i) - w[i] / 10.0).abs() < 1e-12);
        }
        assert!(AliasTable::new(&[0.0]).is_none());
        assert!(AliasTable::new(&[1.0, -1.0, 2.0]).is_none());
    }

    #[test]
    fn distribution_2d_density_integrates_to_one_and_matches_samples() {
        let w = [0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 3.0, 1.0, 1.0];
        let d = Distribution2D::new(&w, 3, 3).unwrap();
        let mut integral = 0.0;
        for j in 0..3 {
            for i in 0..3 {
                integral +=
                    d.pdf(Vec2::new((i as f32 + 0.5) / 3.0, (j as f32 + 0.5) / 3.0)) as f64 / 9.0;
            }
        }
        assert!((integral - 1.0).abs() < 1e-6);
        // cells outside the grid have probability 0, whichever index is out
        assert_eq!((d.pmf(3, 0), d.pmf(0, 3), d.pmf(3, 3)), (0.0, 0.0, 0.0));
        for k in 0..200 {
            let u = Vec2::new((k as f32 * 0.618_034).fract(), (k as f32 + 0.5) / 200.0);
            let (uv, pdf) = d.sample(u);
            assert!(
                pdf > 0.0 && (pdf - d.pdf(uv)).abs() < 1e-5 * pdf,
                "{uv} {pdf}"
            );
        }
    }

    /// `mis_power` as it was before the lane kernel (issue 42, step 3a).
    fn mis_power_reference(pdf_a: f32, pdf_b: f32) -> f32 {
        let a = pdf_a * pdf_a;
        let b = pdf_b * pdf_b;
        if a + b > 0.0 && a.is_finite() {
            a / (a + b)
        } else if a.is_infinite() {
            1.0
        } else {
            0.0
        }
    }

    struct Mis<'a>(&'a [(f32, f32)]);

    impl crate::simd::LaneProgram for Mis<'_> {
        type Output = Vec<f32>;
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Vec<f32> {
            let mut out = Vec::new();
            for chunk in self.0.chunks(L::WIDTH) {
                let (mut a, mut b) = (l.splat(0.0), l.splat(0.0));
                for (i, &(x, y)) in chunk.iter().enumerate() {
                    a.set_lane(i, x);
                    b.set_lane(i, y);
                }
                let w = mis_power_lanes(l, a, b);
                out.extend((0..chunk.len()).map(|i| w.lane(i)));
            }
            out
        }
    }

    /// The power heuristic in lanes against the scalar code of before, on every backend,
    /// on densities with the edges: 0, subnormal, overflowing squares, ∞ and NaN.
    #[test]
    fn mis_power_in_lanes_matches_the_scalar_code() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(0x3157);
        let special = [
            0.0,
            -0.0,
            1e-40,
            1e-20,
            1.0,
            2e19,
            1e30,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ];
        let x = |rng: &mut rand_pcg::Pcg32| match rng.random_range(0..3) {
            0 => special[rng.random_range(0..special.len())],
            _ => rng.random_range(0.0f32..10.0),
        };
        let cases: Vec<(f32, f32)> = (0..16 * 1024).map(|_| (x(&mut rng), x(&mut rng))).collect();
        for b in crate::simd::Backend::all_supported() {
            let got = crate::simd::dispatch(b, Mis(&cases)).expect("supported");
            for (&(pa, pb), g) in cases.iter().zip(got) {
                let w = mis_power_reference(pa, pb);
                assert!(
                    g.to_bits() == w.to_bits() || g.is_nan() && w.is_nan(),
                    "{b}: mis_power({pa}, {pb}) = {g}, scalar {w}"
                );
            }
        }
    }

    /// Bilinear2D against the answers known in closed form: values rising from 0 to 1
    /// across u give the density 2u, so u = √ξ, with v uniform; equal values give the
    /// identity with density 1.
    #[test]
    fn bilinear_2d_inverts_known_densities() {
        let ramp = Bilinear2D::new(&[0.0, 1.0, 0.0, 1.0], 1, 1).unwrap();
        let flat = Bilinear2D::new(&[3.0; 12], 3, 2).unwrap();
        for k in 0..97 {
            let xi = Vec2::new((k as f32 + 0.5) / 97.0, ((k * 37) % 97) as f32 / 97.0);
            let (uv, pdf) = ramp.sample(xi);
            assert!((uv.x - xi.x.sqrt()).abs() < 1e-6, "{uv} for {xi}");
            assert!((uv.y - xi.y).abs() < 1e-6, "{uv} for {xi}");
            assert!((pdf - 2.0 * uv.x).abs() < 1e-5, "{pdf} at {uv}");
            assert!((ramp.pdf(uv) - pdf).abs() < 1e-5);
            let (uv, pdf) = flat.sample(xi);
            assert!((uv - xi).abs().max_element() < 1e-6, "{uv} for {xi}");
            assert!((pdf - 1.0).abs() < 1e-6);
        }
        assert!(Bilinear2D::new(&[0.0; 4], 1, 1).is_none());
        assert!(Bilinear2D::new(&[1.0, -1.0, 1.0, 1.0], 1, 1).is_none());
        assert!(Bilinear2D::new(&[1.0; 5], 1, 1).is_none());
    }

    /// Bilinear2D's samples follow its density: a chi-square test on quarter cells (the
    /// expected share of a rectangle is its area times the bilinear value at its centre,
    /// exactly), α = 0.01; and each sample's density is `pdf` at its point. Red with the
    /// conditional taken from row j alone (not interpolated towards row j + 1).
    #[test]
    fn bilinear_2d_samples_follow_its_density() {
        let (nu, nv) = (5usize, 3usize);
        let values: Vec<f64> = (0..(nu + 1) * (nv + 1))
            .map(|k| ((k * 7919) % 13) as f64 * 0.25 + if k % 5 == 0 { 0.0 } else { 0.1 })
            .collect();
        let d = Bilinear2D::new(&values, nu, nv).unwrap();
        let (bu, bv) = (2 * nu, 2 * nv);
        let n = 400_000usize;
        let mut counts = vec![0u64; bu * bv];
        use rand::RngExt;
        let mut rng = rand_pcg::Pcg32::new(0xb11e, 7);
        for _ in 0..n {
            let (uv, pdf) = d.sample(Vec2::new(rng.random(), rng.random()));
            assert!(
                ((d.pdf(uv) - pdf) / pdf).abs() < 1e-4,
                "{uv}: {pdf} vs {}",
                d.pdf(uv)
            );
            let (i, j) = (
                ((uv.x * bu as f32) as usize).min(bu - 1),
                ((uv.y * bv as f32) as usize).min(bv - 1),
            );
            counts[j * bu + i] += 1;
        }
        let mut chi2 = 0.0;
        let mut total_p = 0.0;
        for j in 0..bv {
            for i in 0..bu {
                let centre = Vec2::new((i as f32 + 0.5) / bu as f32, (j as f32 + 0.5) / bv as f32);
                let p = d.pdf(centre) as f64 / (bu * bv) as f64;
                total_p += p;
                let e = p * n as f64;
                let o = counts[j * bu + i] as f64;
                chi2 += (o - e) * (o - e) / e;
            }
        }
        assert!(
            (total_p - 1.0).abs() < 1e-5,
            "the density integrates to {total_p}"
        );
        let p_value = crate::study::stats::chi2_sf(chi2, (bu * bv - 1) as f64);
        assert!(p_value > 0.01, "chi2 {chi2}, p = {p_value}");
    }
}
