//! Chi-square goodness-of-fit test of a direction sampler against its density, the method
//! Mitsuba and pbrt use to test every BSDF and emitter sampling routine: draw many sampled
//! directions, histogram them on a (cos θ, φ) grid of equal-area cells, compute the expected
//! count of each cell by integrating the claimed pdf over it (composite Simpson rule), pool the
//! cells with small expected counts, and compare with Pearson's statistic.
//!
//! Samplers may fail (return `None`) or produce Dirac-delta directions that the caller leaves
//! out: then the pdf over the sphere integrates to less than one, and the test compares only
//! what lands on the sphere.

use crate::study::stats::chi2_sf;
use glam::Vec3;
use std::f64::consts::PI;

#[derive(Clone, Copy, Debug)]
pub struct Chi2Config {
    /// Bins in cos θ ∈ [−1, 1] (θ from +z).
    pub cos_theta_bins: usize,
    /// Bins in φ ∈ [0, 2π).
    pub phi_bins: usize,
    /// Simpson sub-intervals per cell side for the expected counts (even).
    pub quadrature: usize,
    /// Cells with a smaller expected count are pooled into one.
    pub min_expected: f64,
}

impl Default for Chi2Config {
    fn default() -> Self {
        Chi2Config {
            cos_theta_bins: 40,
            phi_bins: 80,
            quadrature: 8,
            min_expected: 5.0,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Chi2Result {
    /// Pearson's χ² statistic.
    pub statistic: f64,
    pub dof: usize,
    /// P(χ²_dof ≥ statistic); 0 if a sample fell where the pdf integrates to 0.
    pub p_value: f64,
    /// Samples drawn (including failed ones).
    pub samples: usize,
    /// Samples that produced a direction.
    pub landed: usize,
    /// The pdf's integral over the sphere, Σ expected / samples.
    pub pdf_integral: f64,
    /// Samples that landed in cells whose expected count is zero.
    pub samples_in_zero_cells: usize,
}

fn cell_of(d: Vec3, cfg: &Chi2Config) -> Option<usize> {
    let d = d.as_dvec3();
    let len = d.length();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    let d = d / len;
    let ct = ((d.z.clamp(-1.0, 1.0) + 1.0) * 0.5 * cfg.cos_theta_bins as f64) as usize;
    let phi = d.y.atan2(d.x).rem_euclid(2.0 * PI);
    let p = (phi / (2.0 * PI) * cfg.phi_bins as f64) as usize;
    Some(ct.min(cfg.cos_theta_bins - 1) * cfg.phi_bins + p.min(cfg.phi_bins - 1))
}

/// The integral of `pdf` (solid-angle density) over every cell, by the composite Simpson
/// rule in (cos θ, φ), where dω = d(cos θ) dφ.
pub fn integrate_cells(pdf: &impl Fn(Vec3) -> f64, cfg: &Chi2Config) -> Vec<f64> {
    let q = cfg.quadrature.max(2) & !1;
    let (nt, np) = (cfg.cos_theta_bins, cfg.phi_bins);
    let (dct, dphi) = (2.0 / nt as f64, 2.0 * PI / np as f64);
    let simpson = |i: usize| simpson_weight(i, q);
    let mut out = vec![0.0; nt * np];
    for it in 0..nt {
        for ip in 0..np {
            let mut acc = 0.0;
            for a in 0..=q {
                let ct = -1.0 + dct * (it as f64 + a as f64 / q as f64);
                let st = (1.0 - ct * ct).max(0.0).sqrt();
                for b in 0..=q {
                    let phi = dphi * (ip as f64 + b as f64 / q as f64);
                    let d = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32);
                    let v = pdf(d);
                    acc += simpson(a) * simpson(b) * if v.is_finite() { v } else { 0.0 };
                }
            }
            out[it * np + ip] = acc * (dct / q as f64 / 3.0) * (dphi / q as f64 / 3.0);
        }
    }
    out
}

/// Runs the test: `sample(i)` draws the i-th direction (`None` for a failed or delta
/// sample), `pdf` is the claimed solid-angle density of the non-delta part.
pub fn chi2_test(
    samples: usize,
    sample: impl FnMut(usize) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
    cfg: &Chi2Config,
) -> Chi2Result {
    let (observed, landed) = observe(samples, sample, cfg);
    let integral = integrate_cells(&pdf, cfg);
    statistic(samples, landed, &observed, &integral, cfg)
}

/// As [`chi2_test`], with the expected counts from [`integrate_cells_adaptive`]: for pdfs
/// with narrow peaks or cut-offs inside cells, which a fixed Simpson grid misjudges.
/// `tolerance` bounds the quadrature error of each cell's probability.
pub fn chi2_test_adaptive(
    samples: usize,
    sample: impl FnMut(usize) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
    cfg: &Chi2Config,
    tolerance: f64,
) -> Chi2Result {
    let (observed, landed) = observe(samples, sample, cfg);
    let integral = integrate_cells_adaptive(&pdf, cfg, tolerance);
    statistic(samples, landed, &observed, &integral, cfg)
}

fn observe(
    samples: usize,
    mut sample: impl FnMut(usize) -> Option<Vec3>,
    cfg: &Chi2Config,
) -> (Vec<f64>, usize) {
    let mut observed = vec![0.0f64; cfg.cos_theta_bins * cfg.phi_bins];
    let mut landed = 0;
    for i in 0..samples {
        if let Some(c) = sample(i).and_then(|d| cell_of(d, cfg)) {
            observed[c] += 1.0;
            landed += 1;
        }
    }
    (observed, landed)
}

/// Weight of node `i` of the composite Simpson rule with `q` (even) intervals: 1, 4, 2, 4, ...,
/// 4, 1.
fn simpson_weight(i: usize, q: usize) -> f64 {
    if i == 0 || i == q {
        1.0
    } else if i % 2 == 1 {
        4.0
    } else {
        2.0
    }
}

/// A pdf value at (cos θ, φ) given as (cos θ, sin φ, cos φ); non-finite values count as 0.
#[inline]
fn pdf_at(pdf: &impl Fn(Vec3) -> f64, ct: f64, sin_phi: f64, cos_phi: f64) -> f64 {
    let st = (1.0 - ct * ct).max(0.0).sqrt();
    let v = pdf(Vec3::new(
        (st * cos_phi) as f32,
        (st * sin_phi) as f32,
        ct as f32,
    ));
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// The pdf on the 5 × 5 nodes of Simpson's rule (4 intervals per side) on the rectangle
/// `r` = [cos θ0, cos θ1, φ0, φ1], and the rule's estimate of the integral.
fn simpson_grid5(pdf: &impl Fn(Vec3) -> f64, r: [f64; 4]) -> ([[f64; 5]; 5], f64) {
    let [c0, c1, p0, p1] = r;
    let (hc, hp) = ((c1 - c0) / 4.0, (p1 - p0) / 4.0);
    let sin_cos: [(f64, f64); 5] = std::array::from_fn(|b| (p0 + hp * b as f64).sin_cos());
    let grid = std::array::from_fn(|a| {
        let ct = (c0 + hc * a as f64).clamp(-1.0, 1.0);
        std::array::from_fn(|b| pdf_at(pdf, ct, sin_cos[b].0, sin_cos[b].1))
    });
    (grid, simpson5(&grid, hc, hp))
}

/// Simpson's rule on 5 × 5 node values with node spacings `hc`, `hp`.
fn simpson5(v: &[[f64; 5]; 5], hc: f64, hp: f64) -> f64 {
    let w = |i: usize| simpson_weight(i, 4);
    let mut acc = 0.0;
    for (a, row) in v.iter().enumerate() {
        for (b, x) in row.iter().enumerate() {
            acc += w(a) * w(b) * x;
        }
    }
    acc * hc * hp / 9.0
}

/// Adaptive Simpson quadrature on a rectangle `r` whose 5 × 5 node values `coarse` gave the
/// estimate `whole`: compares it with the sum over its four quarters and recurses where they
/// differ by more than `tol` (split between the quarters), up to `depth` levels. The
/// quarters' nodes are the 9 × 9 nodes of the rectangle, of which the 25 of `coarse` are
/// already known: each level evaluates the pdf 56 times, not 100.
fn adaptive_rect(
    pdf: &impl Fn(Vec3) -> f64,
    r: [f64; 4],
    coarse: &[[f64; 5]; 5],
    whole: f64,
    tol: f64,
    depth: u32,
) -> f64 {
    let [c0, c1, p0, p1] = r;
    let (cm, pm) = (0.5 * (c0 + c1), 0.5 * (p0 + p1));
    let (hc, hp) = ((c1 - c0) / 8.0, (p1 - p0) / 8.0);
    let sin_cos: [(f64, f64); 9] = std::array::from_fn(|b| (p0 + hp * b as f64).sin_cos());
    let mut fine = [[0.0f64; 9]; 9];
    for (a, row) in fine.iter_mut().enumerate() {
        let ct = (c0 + hc * a as f64).clamp(-1.0, 1.0);
        for (b, x) in row.iter_mut().enumerate() {
            *x = if a % 2 == 0 && b % 2 == 0 {
                coarse[a / 2][b / 2]
            } else {
                pdf_at(pdf, ct, sin_cos[b].0, sin_cos[b].1)
            };
        }
    }
    // Quarter (i, j): cos θ half i, φ half j, in the order [c0, cm] × [p0, pm], [cm, c1] ×
    // [p0, pm], [c0, cm] × [pm, p1], [cm, c1] × [pm, p1].
    let quads = [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(i, j)| {
        let rect = [[c0, cm][i], [cm, c1][i], [p0, pm][j], [pm, p1][j]];
        let v: [[f64; 5]; 5] =
            std::array::from_fn(|a| std::array::from_fn(|b| fine[4 * i + a][4 * j + b]));
        let est = simpson5(&v, (rect[1] - rect[0]) / 4.0, (rect[3] - rect[2]) / 4.0);
        (rect, v, est)
    });
    let sum: f64 = quads.iter().map(|q| q.2).sum();
    // Also stop at the pdf's own precision (it is evaluated at f32 directions).
    if depth == 0 || (sum - whole).abs() <= tol.max(1e-5 * sum.abs()) {
        return sum;
    }
    quads
        .iter()
        .map(|(rect, v, est)| adaptive_rect(pdf, *rect, v, *est, 0.25 * tol, depth - 1))
        .sum()
}

/// The integral of `pdf` over every cell by adaptive Simpson quadrature (absolute error per
/// cell about `tolerance`, or 1e-5 relative; at most 8 levels of subdivision).
pub fn integrate_cells_adaptive(
    pdf: &impl Fn(Vec3) -> f64,
    cfg: &Chi2Config,
    tolerance: f64,
) -> Vec<f64> {
    let (nt, np) = (cfg.cos_theta_bins, cfg.phi_bins);
    let (dct, dphi) = (2.0 / nt as f64, 2.0 * PI / np as f64);
    let mut out = vec![0.0; nt * np];
    for it in 0..nt {
        for ip in 0..np {
            let r = [
                -1.0 + dct * it as f64,
                -1.0 + dct * (it + 1) as f64,
                dphi * ip as f64,
                dphi * (ip + 1) as f64,
            ];
            let (grid, whole) = simpson_grid5(pdf, r);
            out[it * np + ip] = adaptive_rect(pdf, r, &grid, whole, tolerance, 8);
        }
    }
    out
}

fn statistic(
    samples: usize,
    landed: usize,
    observed: &[f64],
    integral: &[f64],
    cfg: &Chi2Config,
) -> Chi2Result {
    let expected: Vec<f64> = integral.iter().map(|p| p * samples as f64).collect();
    let samples_in_zero_cells = observed
        .iter()
        .zip(&expected)
        .filter(|(_, &e)| e <= 0.0)
        .map(|(o, _)| *o as usize)
        .sum();
    // Pool the cells with small expected counts (Mitsuba's and pbrt's practice).
    let (mut pooled_obs, mut pooled_exp) = (0.0, 0.0);
    let mut statistic = 0.0;
    let mut cells = 0usize;
    for (o, e) in observed.iter().zip(&expected) {
        if *e < cfg.min_expected {
            pooled_obs += o;
            pooled_exp += e;
        } else {
            statistic += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    if pooled_exp > 0.0 {
        statistic += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        cells += 1;
    }
    let dof = cells.saturating_sub(1).max(1);
    let p_value = if samples_in_zero_cells > 0 {
        0.0
    } else {
        chi2_sf(statistic, dof as f64)
    };
    Chi2Result {
        statistic,
        dof,
        p_value,
        samples,
        landed,
        pdf_integral: expected.iter().sum::<f64>() / samples as f64,
        samples_in_zero_cells,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;
    use crate::sampling::{square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf};

    #[test]
    fn accepts_a_correct_sampler_and_rejects_a_wrong_pdf() {
        let cfg = Chi2Config::default();
        let n = 200_000;
        let draw = |i: usize| {
            Some(square_to_cosine_hemisphere(
                SampleStream::new(3, i as u64, 0).next_2d(),
            ))
        };
        let good = chi2_test(n, draw, |d| square_to_cosine_hemisphere_pdf(d) as f64, &cfg);
        assert!(good.p_value > 0.001, "{good:?}");
        assert!((good.pdf_integral - 1.0).abs() < 1e-3);
        // claim a uniform hemisphere instead: must be rejected decisively
        let bad = chi2_test(n, draw, |d| if d.z > 0.0 { 0.5 / PI } else { 0.0 }, &cfg);
        assert!(bad.p_value < 1e-10, "{bad:?}");
        // half the samples fail: the pdf integral 0.5 still matches
        let half = chi2_test(
            n,
            |i| if i % 2 == 0 { draw(i) } else { None },
            |d| 0.5 * square_to_cosine_hemisphere_pdf(d) as f64,
            &cfg,
        );
        assert!(half.p_value > 0.001 && half.landed == n / 2, "{half:?}");
    }

    #[test]
    fn adaptive_quadrature_resolves_a_narrow_peak() {
        // A normalised narrow cap around a direction inside a cell.
        let c = Vec3::new(0.3, 0.2, 0.5).normalize();
        let k = 300.0f64; // von Mises–Fisher concentration: width ~ 1/sqrt(k) = 3.3°
        let vmf = |d: Vec3| {
            k / (2.0 * PI * (1.0 - (-2.0 * k).exp())) * (k * (d.dot(c) as f64 - 1.0)).exp()
        };
        let cfg = Chi2Config::default();
        let total: f64 = integrate_cells_adaptive(&vmf, &cfg, 1e-8).iter().sum();
        assert!((total - 1.0).abs() < 1e-4, "{total}");
    }

    /// A density linear in cos θ, which Simpson's rule integrates exactly: every cell
    /// matches its closed form, ((c1 − c0) + (c1² − c0²) / 2) Δφ / 4π, to the f32 rounding of
    /// the directions, and no cell is subdivided, so the pdf is evaluated 25 + 56 times per
    /// cell: the coarse nodes, then the quarters' nodes that are not coarse ones. Quarters
    /// that took their reused nodes from the wrong places would disagree with the coarse
    /// estimate and subdivide.
    #[test]
    fn adaptive_quadrature_reuses_the_coarse_nodes() {
        let calls = std::cell::Cell::new(0usize);
        let f = |d: Vec3| {
            calls.set(calls.get() + 1);
            (1.0 + d.z as f64) / (4.0 * PI)
        };
        let cfg = Chi2Config::default();
        let cells = integrate_cells_adaptive(&f, &cfg, 1e-12);
        let (nt, np) = (cfg.cos_theta_bins, cfg.phi_bins);
        assert_eq!(calls.get(), 81 * nt * np);
        let dphi = 2.0 * PI / np as f64;
        for it in 0..nt {
            let c0 = -1.0 + 2.0 * it as f64 / nt as f64;
            let c1 = -1.0 + 2.0 * (it + 1) as f64 / nt as f64;
            let exact = ((c1 - c0) + 0.5 * (c1 * c1 - c0 * c0)) * dphi / (4.0 * PI);
            for ip in 0..np {
                let got = cells[it * np + ip];
                assert!(
                    (got - exact).abs() <= 1e-6 * exact,
                    "cell ({it}, {ip}): {got} vs {exact}"
                );
            }
        }
    }

    /// A density cut off at cos θ = 0.013, inside a row of cells, which the quadrature
    /// subdivides to its last level: every cell against its closed form, ∫ (1 + c) dc Δφ / N
    /// over the part above the cut. Cells away from the cut to the f32 rounding of the
    /// directions (1e-6); cells across it to the mass of the finest rectangles along the cut
    /// (1/256 of a cell's height: 1% of the cell). And the work: Simpson's rule is exact on
    /// either side of the cut, so of the four quarters of a rectangle only the two the cut
    /// crosses are subdivided: in each cell of that row at most 1 + 4 (1 + 2 + … + 2⁷) =
    /// 1,021 rectangles get their quarters' nodes, 56 new evaluations each. Quarters that
    /// hand the wrong nodes down to their subdivisions heal the answer by subdividing far
    /// more (seen: 24 and 38 times this bound, with the nodes transposed or the quarters
    /// swapped).
    #[test]
    fn adaptive_quadrature_resolves_a_cut_across_cells() {
        let cut = 0.013f64;
        let norm = 2.0 * PI * ((1.0 - cut) + 0.5 * (1.0 - cut * cut));
        let calls = std::cell::Cell::new(0usize);
        let f = |d: Vec3| {
            calls.set(calls.get() + 1);
            let z = d.z as f64;
            if z > cut {
                (1.0 + z) / norm
            } else {
                0.0
            }
        };
        let cfg = Chi2Config::default();
        let cells = integrate_cells_adaptive(&f, &cfg, 1e-12);
        let (nt, np) = (cfg.cos_theta_bins, cfg.phi_bins);
        let bound = 81 * nt * np + np * 1021 * 56;
        assert!(
            calls.get() <= bound,
            "{} evaluations, more than {bound}",
            calls.get()
        );
        let dphi = 2.0 * PI / np as f64;
        for it in 0..nt {
            let c1 = -1.0 + 2.0 * (it + 1) as f64 / nt as f64;
            let c0 = (-1.0 + 2.0 * it as f64 / nt as f64).max(cut);
            let exact = ((c1 - c0) + 0.5 * (c1 * c1 - c0 * c0)).max(0.0) * dphi / norm;
            let crosses = c0 == cut && c1 > cut;
            for ip in 0..np {
                let got = cells[it * np + ip];
                let bound = if crosses { 1e-2 * exact } else { 1e-6 * exact };
                assert!(
                    (got - exact).abs() <= bound,
                    "cell ({it}, {ip}): {got} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn a_sample_where_the_pdf_is_zero_fails() {
        let cfg = Chi2Config::default();
        let r = chi2_test(
            1000,
            |_| Some(Vec3::new(0.0, 0.0, -1.0)),
            |d| if d.z > 0.0 { 0.5 / PI } else { 0.0 },
            &cfg,
        );
        assert_eq!(r.p_value, 0.0);
    }
}
