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

/// Simpson's rule on a rectangle of (cos θ, φ) with `q` (even) intervals per side.
fn simpson_rect(pdf: &impl Fn(Vec3) -> f64, ct0: f64, ct1: f64, p0: f64, p1: f64, q: usize) -> f64 {
    let w = |i: usize| simpson_weight(i, q);
    let (hc, hp) = ((ct1 - ct0) / q as f64, (p1 - p0) / q as f64);
    let mut acc = 0.0;
    // (sin φ, cos φ) of the column nodes, once per rectangle rather than once per node.
    let sin_cos: Vec<(f64, f64)> = (0..=q).map(|b| (p0 + hp * b as f64).sin_cos()).collect();
    for a in 0..=q {
        let ct = (ct0 + hc * a as f64).clamp(-1.0, 1.0);
        let st = (1.0 - ct * ct).max(0.0).sqrt();
        for (b, &(sin_phi, cos_phi)) in sin_cos.iter().enumerate() {
            let d = Vec3::new((st * cos_phi) as f32, (st * sin_phi) as f32, ct as f32);
            let v = pdf(d);
            acc += w(a) * w(b) * if v.is_finite() { v } else { 0.0 };
        }
    }
    acc * hc * hp / 9.0
}

/// Adaptive Simpson quadrature on a rectangle: compares the estimate with the sum over its
/// four quarters and recurses where they differ by more than `tol` (split between the
/// quarters), up to `depth` levels.
fn adaptive_rect(pdf: &impl Fn(Vec3) -> f64, r: [f64; 4], whole: f64, tol: f64, depth: u32) -> f64 {
    let [c0, c1, p0, p1] = r;
    let (cm, pm) = (0.5 * (c0 + c1), 0.5 * (p0 + p1));
    let quads = [
        [c0, cm, p0, pm],
        [cm, c1, p0, pm],
        [c0, cm, pm, p1],
        [cm, c1, pm, p1],
    ];
    let parts = quads.map(|q| simpson_rect(pdf, q[0], q[1], q[2], q[3], 4));
    let sum: f64 = parts.iter().sum();
    // Also stop at the pdf's own precision (it is evaluated at f32 directions).
    if depth == 0 || (sum - whole).abs() <= tol.max(1e-5 * sum.abs()) {
        return sum;
    }
    quads
        .iter()
        .zip(parts)
        .map(|(q, w)| adaptive_rect(pdf, *q, w, 0.25 * tol, depth - 1))
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
            let whole = simpson_rect(pdf, r[0], r[1], r[2], r[3], 4);
            out[it * np + ip] = adaptive_rect(pdf, r, whole, tolerance, 8);
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
