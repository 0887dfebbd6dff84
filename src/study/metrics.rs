//! Image error metrics and the per-pixel z-test against a reference, shared by the tests,
//! the validation study and the command line.

use crate::io::exr::RgbImage;
use crate::study::stats::{normal_critical_z, sidak};

/// Per-channel mean of an image over its finite values (NaN and infinite values, counted by
/// [`nonfinite_pixels`] and [`ErrorMetrics::nonfinite`], are left out; 0 if none is finite).
pub fn channel_means(rgb: &[[f32; 3]]) -> [f64; 3] {
    std::array::from_fn(|c| {
        let (mut sum, mut n) = (0.0, 0usize);
        for v in rgb.iter().map(|p| p[c] as f64).filter(|v| v.is_finite()) {
            sum += v;
            n += 1;
        }
        sum / n.max(1) as f64
    })
}

/// Pixels with at least one NaN or infinite channel.
pub fn nonfinite_pixels(rgb: &[[f32; 3]]) -> usize {
    rgb.iter()
        .filter(|p| p.iter().any(|v| !v.is_finite()))
        .count()
}

/// Error metrics of `a` against the reference `b` (same size), over all pixel-channels.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorMetrics {
    pub rmse: f64,
    pub mse: f64,
    /// Mean of (a − b)² / (b² + 1e-2) (relative MSE with the usual 1e-2 guard).
    pub rel_mse: f64,
    pub mae: f64,
    pub max_abs: f64,
    pub mean_a: [f64; 3],
    pub mean_b: [f64; 3],
    /// Pixel-channels of `a` or `b` that are NaN or infinite (excluded from the sums).
    pub nonfinite: usize,
}

pub fn error_metrics(a: &[[f32; 3]], b: &[[f32; 3]]) -> ErrorMetrics {
    let (mut se, mut rel, mut ae, mut max_abs) = (0.0, 0.0, 0.0, 0.0f64);
    let mut n = 0usize;
    let mut nonfinite = 0;
    for (pa, pb) in a.iter().zip(b) {
        for c in 0..3 {
            let (x, y) = (pa[c] as f64, pb[c] as f64);
            if !(x.is_finite() && y.is_finite()) {
                nonfinite += 1;
                continue;
            }
            let d = x - y;
            se += d * d;
            rel += d * d / (y * y + 1e-2);
            ae += d.abs();
            max_abs = max_abs.max(d.abs());
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    ErrorMetrics {
        rmse: (se / n).sqrt(),
        mse: se / n,
        rel_mse: rel / n,
        mae: ae / n,
        max_abs,
        mean_a: channel_means(a),
        mean_b: channel_means(b),
        nonfinite,
    }
}

/// Outcome of the per-pixel, per-channel z-test.
#[derive(Clone, Debug, PartialEq)]
pub struct ZTest {
    /// Pixel-channels tested.
    pub tests: usize,
    /// Pixel-channels with |z| above the Šidák-corrected critical value.
    pub failures: usize,
    /// The critical |z|.
    pub z_critical: f64,
    /// Largest |z| seen.
    pub z_max: f64,
}

impl ZTest {
    pub fn pass_rate(&self) -> f64 {
        1.0 - self.failures as f64 / self.tests.max(1) as f64
    }

    /// Mitsuba's render-regression criterion: at least 99.75% of pixel-channels pass.
    pub fn passed(&self) -> bool {
        self.pass_rate() >= 0.9975
    }
}

/// Floor on per-sample variances, as in Mitsuba's render tests, so that pixels whose
/// estimates happen to be constant do not produce infinite z.
pub const VARIANCE_FLOOR: f64 = 1e-4;

/// z = |a − b| / sqrt(var_a / n_a + var_b / n_b) per pixel and channel, with per-sample
/// variances (floored at [`VARIANCE_FLOOR`]); two-sided, Šidák-corrected over all
/// pixel-channels at family level `alpha`.
pub fn z_test(a: &RgbImage, spp_a: f64, b: &RgbImage, spp_b: f64, alpha: f64) -> Option<ZTest> {
    let va = a.variance.as_ref()?;
    let vb = b.variance.as_ref()?;
    let tests = a.rgb.len() * 3;
    let z_critical = normal_critical_z(sidak(alpha, tests));
    let mut failures = 0;
    let mut z_max = 0.0f64;
    for i in 0..a.rgb.len().min(b.rgb.len()) {
        for c in 0..3 {
            let var = (va[i][c] as f64).max(VARIANCE_FLOOR) / spp_a
                + (vb[i][c] as f64).max(VARIANCE_FLOOR) / spp_b;
            let z = (a.rgb[i][c] as f64 - b.rgb[i][c] as f64).abs() / var.sqrt();
            let z = if z.is_nan() { f64::INFINITY } else { z };
            z_max = z_max.max(z);
            if z > z_critical {
                failures += 1;
            }
        }
    }
    Some(ZTest {
        tests,
        failures,
        z_critical,
        z_max,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn img(v: &[[f32; 3]], var: f32) -> RgbImage {
        RgbImage {
            width: v.len(),
            height: 1,
            rgb: v.to_vec(),
            variance: Some(vec![[var; 3]; v.len()]),
            attributes: BTreeMap::new(),
        }
    }

    #[test]
    fn metrics_exact_values() {
        let a = [[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]];
        let b = [[1.0, 1.0, 1.0], [0.0, 0.0, 4.0]];
        let m = error_metrics(&a, &b);
        // differences: 0, 1, 2, 0, 0, −4 → squares 0+1+4+16 = 21 over 6
        assert!((m.mse - 3.5).abs() < 1e-12);
        assert!((m.rmse - 3.5f64.sqrt()).abs() < 1e-12);
        assert!((m.mae - 7.0 / 6.0).abs() < 1e-12);
        assert_eq!(m.max_abs, 4.0);
        let rel = (1.0 / 1.01 + 4.0 / 1.01 + 16.0 / 16.01) / 6.0;
        assert!((m.rel_mse - rel).abs() < 1e-12);
        assert_eq!(m.mean_a, [0.5, 1.0, 1.5]);
        let m = error_metrics(&[[f32::NAN, 0.0, 0.0]], &[[0.0; 3]]);
        assert_eq!(m.nonfinite, 1);
        // Means leave non-finite values out, per channel.
        let c = [
            [f32::NAN, 1.0, 2.0],
            [3.0, f32::INFINITY, 4.0],
            [5.0, 3.0, 6.0],
        ];
        assert_eq!(channel_means(&c), [4.0, 2.0, 4.0]);
        assert_eq!(nonfinite_pixels(&c), 2);
    }

    #[test]
    fn z_test_flags_a_biased_pixel_only() {
        let n = 1000;
        let b: Vec<[f32; 3]> = vec![[1.0; 3]; n];
        let mut a = b.clone();
        a[7][1] = 1.5; // sd of the difference sqrt(2/100) = 0.141: z = 3.5, below critical
        a[9][2] = 3.0; // z = 14: fails
        let t = z_test(&img(&a, 1.0), 100.0, &img(&b, 1.0), 100.0, 0.01).unwrap();
        assert_eq!(t.tests, 3 * n);
        assert_eq!(t.failures, 1);
        assert!((t.z_max - 2.0 / (0.02f64).sqrt()).abs() < 1e-5);
        // Šidák over 3000 tests at 0.01: per-test level 3.35e-6, two-sided critical |z| ≈ 4.65
        assert!(t.z_critical > 4.6 && t.z_critical < 4.7, "{}", t.z_critical);
    }
}
