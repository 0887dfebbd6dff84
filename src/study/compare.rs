//! `penumbra compare`: the error metrics of one image against another (RMSE, relative MSE,
//! MAE, max abs error, per-channel means, non-finite pixels; [`crate::study::metrics`]), the per-pixel
//! z-test when a per-sample variance is known ([`crate::study::metrics::z_test`], as in the
//! validation study), and the signed per-pixel difference that the false-colour diff image
//! shows ([`crate::study::plot::write_diff_png`]).
//!
//! The second image, B, is the reference: relative MSE divides by B², relative mean
//! differences by B's means, and a positive difference means A is brighter.

use crate::error::{Error, Result};
use crate::io::exr::RgbImage;
use crate::study::metrics::{error_metrics, nonfinite_pixels, z_test, ErrorMetrics, ZTest};
use serde::Serialize;

/// Which per-sample variances the z-test used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VarianceSource {
    /// Each image's own variance channels.
    Both,
    /// Only A has variance channels: A's per-sample variance stands in for B's too.
    OnlyA,
    /// Only B has variance channels: B's per-sample variance stands in for A's too.
    OnlyB,
}

/// The z-test of A against B, or why it was not run.
#[derive(Clone, Debug, PartialEq)]
pub enum ZOutcome {
    Ran {
        test: ZTest,
        source: VarianceSource,
        spp_a: f64,
        spp_b: f64,
    },
    Skipped(String),
}

impl ZOutcome {
    pub fn test(&self) -> Option<&ZTest> {
        match self {
            ZOutcome::Ran { test, .. } => Some(test),
            ZOutcome::Skipped(_) => None,
        }
    }

    /// One sentence on how the test was made (or why not).
    pub fn note(&self) -> String {
        match self {
            ZOutcome::Ran { source, .. } => match source {
                VarianceSource::Both => "per-sample variances of both images".into(),
                VarianceSource::OnlyA => {
                    "only A has variance channels: A's per-sample variance is used for both \
                     terms"
                        .into()
                }
                VarianceSource::OnlyB => {
                    "only B has variance channels: B's per-sample variance is used for both \
                     terms"
                        .into()
                }
            },
            ZOutcome::Skipped(why) => why.clone(),
        }
    }
}

/// The per-pixel z-test of `a` against `b` ([`z_test`]) at family level `alpha`, with each
/// image's samples per pixel. When only one image has a per-sample variance, it is used for
/// both terms (the images estimate the same pixels, so their per-sample variances agree up to
/// the bias being tested). Skipped, with the reason, when neither has one or a needed spp is
/// unknown.
pub fn z_test_either(
    a: &RgbImage,
    spp_a: Option<f64>,
    b: &RgbImage,
    spp_b: Option<f64>,
    alpha: f64,
) -> ZOutcome {
    let source = match (a.variance.is_some(), b.variance.is_some()) {
        (true, true) => VarianceSource::Both,
        (true, false) => VarianceSource::OnlyA,
        (false, true) => VarianceSource::OnlyB,
        (false, false) => {
            return ZOutcome::Skipped(
                "neither image has variance channels (variance.R/G/B; penumbra render \
                 --variance writes them)"
                    .into(),
            )
        }
    };
    let (Some(spp_a), Some(spp_b)) = (spp_a, spp_b) else {
        let which = if spp_a.is_none() { "A" } else { "B" };
        let flag = if spp_a.is_none() { "a" } else { "b" };
        return ZOutcome::Skipped(format!(
            "{which} has no `spp` header attribute: give its samples per pixel with --spp-{flag}"
        ));
    };
    let borrow = |img: &RgbImage, from: &RgbImage| RgbImage {
        variance: from.variance.clone(),
        ..img.clone()
    };
    let test = match source {
        VarianceSource::Both => z_test(a, spp_a, b, spp_b, alpha),
        VarianceSource::OnlyA => z_test(a, spp_a, &borrow(b, a), spp_b, alpha),
        VarianceSource::OnlyB => z_test(&borrow(a, b), spp_a, b, spp_b, alpha),
    };
    match test {
        Some(test) => ZOutcome::Ran {
            test,
            source,
            spp_a,
            spp_b,
        },
        None => ZOutcome::Skipped("no variance".into()),
    }
}

/// Everything `compare` measures.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    pub width: usize,
    pub height: usize,
    pub metrics: ErrorMetrics,
    /// Per channel, (mean_a − mean_b) / |mean_b| (0 when both are 0, infinite when only
    /// mean_b is).
    pub mean_rel_diff: [f64; 3],
    /// Pixels of A and of B with a NaN or infinite channel.
    pub nonfinite_pixels: [usize; 2],
    pub z: ZOutcome,
}

/// (a − b) / |b|, 0 when both are 0.
pub fn relative_difference(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b) / b.abs()
    }
}

/// Compares `a` with the reference `b` (same size). `spp_a`, `spp_b` override the images'
/// `spp` header attributes for the z-test, at family level `alpha`.
pub fn compare(
    a: &RgbImage,
    b: &RgbImage,
    spp_a: Option<f64>,
    spp_b: Option<f64>,
    alpha: f64,
) -> Result<Comparison> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::Invalid(format!(
            "the images differ in size: A is {}x{}, B is {}x{}",
            a.width, a.height, b.width, b.height
        )));
    }
    let metrics = error_metrics(&a.rgb, &b.rgb);
    let mean_rel_diff =
        std::array::from_fn(|c| relative_difference(metrics.mean_a[c], metrics.mean_b[c]));
    let z = z_test_either(a, spp_a.or(a.spp()), b, spp_b.or(b.spp()), alpha);
    Ok(Comparison {
        width: a.width,
        height: a.height,
        metrics,
        mean_rel_diff,
        nonfinite_pixels: [nonfinite_pixels(&a.rgb), nonfinite_pixels(&b.rgb)],
        z,
    })
}

/// The signed per-pixel difference the diff image shows: the mean over R, G, B of a − b;
/// NaN where either pixel has a non-finite channel.
pub fn signed_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> Vec<f64> {
    a.iter()
        .zip(b)
        .map(|(pa, pb)| {
            let d: f64 = (0..3).map(|c| pa[c] as f64 - pb[c] as f64).sum::<f64>() / 3.0;
            if d.is_finite() {
                d
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// The `q`-quantile (0 ≤ q ≤ 1; nearest rank) of |values| over the finite ones; `None` if
/// there are none.
pub fn abs_quantile(values: &[f64], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values
        .iter()
        .filter(|x| x.is_finite())
        .map(|x| x.abs())
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((q.clamp(0.0, 1.0) * v.len() as f64).ceil() as usize).clamp(1, v.len());
    Some(v[rank - 1])
}

/// The quantile of |Δ| that sets the diff image's colour range by default: the top 1% of
/// pixels saturate, so that a few fireflies do not wash the map out.
pub const DIFF_RANGE_QUANTILE: f64 = 0.99;

/// The diff image's default half-range: the [`DIFF_RANGE_QUANTILE`] of |Δ|, else the largest
/// |Δ| if that is 0, else 1 (identical images).
pub fn default_diff_range(diff: &[f64]) -> f64 {
    let q = abs_quantile(diff, DIFF_RANGE_QUANTILE).unwrap_or(0.0);
    if q > 0.0 {
        return q;
    }
    let max = abs_quantile(diff, 1.0).unwrap_or(0.0);
    if max > 0.0 {
        max
    } else {
        1.0
    }
}

/// The JSON form of a [`Comparison`] (`compare --json`).
#[derive(Serialize)]
pub struct ComparisonJson<'a> {
    pub a: &'a str,
    pub b: &'a str,
    pub width: usize,
    pub height: usize,
    pub rmse: f64,
    pub mse: f64,
    pub rel_mse: f64,
    pub mae: f64,
    pub max_abs: f64,
    pub mean_a: [f64; 3],
    pub mean_b: [f64; 3],
    pub mean_rel_diff: [f64; 3],
    pub nonfinite_pixels_a: usize,
    pub nonfinite_pixels_b: usize,
    /// Pixel-channels left out of the metrics because A or B is non-finite there.
    pub nonfinite_pixel_channels: usize,
    pub z_test: Option<ZTestJson>,
    pub z_test_note: String,
    /// The diff image written, if any.
    pub diff: Option<DiffJson<'a>>,
}

#[derive(Serialize)]
pub struct ZTestJson {
    pub pass_rate: f64,
    pub passed: bool,
    pub tests: usize,
    pub failures: usize,
    pub z_critical: f64,
    pub z_max: f64,
    pub alpha: f64,
    pub spp_a: f64,
    pub spp_b: f64,
    pub variance: VarianceSource,
}

#[derive(Serialize)]
pub struct DiffJson<'a> {
    pub path: &'a str,
    /// The colour map's half-range: ±range maps to full blue / red.
    pub range: f64,
}

impl Comparison {
    pub fn to_json<'a>(
        &self,
        a: &'a str,
        b: &'a str,
        alpha: f64,
        diff: Option<DiffJson<'a>>,
    ) -> ComparisonJson<'a> {
        let m = &self.metrics;
        ComparisonJson {
            a,
            b,
            width: self.width,
            height: self.height,
            rmse: m.rmse,
            mse: m.mse,
            rel_mse: m.rel_mse,
            mae: m.mae,
            max_abs: m.max_abs,
            mean_a: m.mean_a,
            mean_b: m.mean_b,
            mean_rel_diff: self.mean_rel_diff,
            nonfinite_pixels_a: self.nonfinite_pixels[0],
            nonfinite_pixels_b: self.nonfinite_pixels[1],
            nonfinite_pixel_channels: m.nonfinite,
            z_test: match &self.z {
                ZOutcome::Ran {
                    test,
                    source,
                    spp_a,
                    spp_b,
                } => Some(ZTestJson {
                    pass_rate: test.pass_rate(),
                    passed: test.passed(),
                    tests: test.tests,
                    failures: test.failures,
                    z_critical: test.z_critical,
                    z_max: test.z_max,
                    alpha,
                    spp_a: *spp_a,
                    spp_b: *spp_b,
                    variance: *source,
                }),
                ZOutcome::Skipped(_) => None,
            },
            z_test_note: self.z.note(),
            diff,
        }
    }

    /// The human-readable report.
    pub fn text(&self, a: &str, b: &str) -> String {
        use std::fmt::Write as _;
        let m = &self.metrics;
        let mut s = String::new();
        let _ = writeln!(s, "A: {a}\nB: {b} (reference)");
        let _ = writeln!(s, "{}x{} pixels", self.width, self.height);
        let _ = writeln!(s, "RMSE          {:.6e}", m.rmse);
        let _ = writeln!(s, "MSE           {:.6e}", m.mse);
        let _ = writeln!(
            s,
            "relative MSE  {:.6e}   (mean of (A-B)^2 / (B^2 + 0.01))",
            m.rel_mse
        );
        let _ = writeln!(s, "MAE           {:.6e}", m.mae);
        let _ = writeln!(s, "max |A-B|     {:.6e}", m.max_abs);
        let _ = writeln!(s, "channel   mean A        mean B        (A-B)/B");
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let _ = writeln!(
                s,
                "{name}         {:<13.6e} {:<13.6e} {:+.4}%",
                m.mean_a[c],
                m.mean_b[c],
                100.0 * self.mean_rel_diff[c]
            );
        }
        let _ = writeln!(
            s,
            "non-finite pixels: A {}, B {} ({} pixel-channels left out of the metrics)",
            self.nonfinite_pixels[0], self.nonfinite_pixels[1], m.nonfinite
        );
        match &self.z {
            ZOutcome::Ran {
                test, spp_a, spp_b, ..
            } => {
                let _ = writeln!(
                    s,
                    "z-test: pass rate {:.4}% ({} of {} pixel-channels above |z| = {:.3}; \
                     max |z| {:.2}) -> {}; spp A {}, B {}; {}",
                    100.0 * test.pass_rate(),
                    test.failures,
                    test.tests,
                    test.z_critical,
                    test.z_max,
                    if test.passed() {
                        "pass (>= 99.75%)"
                    } else {
                        "FAIL (< 99.75%)"
                    },
                    spp_a,
                    spp_b,
                    self.z.note()
                );
            }
            ZOutcome::Skipped(why) => {
                let _ = writeln!(s, "z-test: not run: {why}");
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(|i| -(i as f64)).chain([f64::NAN]).collect();
        assert_eq!(abs_quantile(&v, 0.99), Some(99.0));
        assert_eq!(abs_quantile(&v, 1.0), Some(100.0));
        assert_eq!(abs_quantile(&v, 0.0), Some(1.0));
        assert_eq!(abs_quantile(&[f64::NAN], 0.5), None);
        assert_eq!(default_diff_range(&[0.0, 0.0]), 1.0);
    }

    #[test]
    fn relative_difference_edge_cases() {
        assert_eq!(relative_difference(0.0, 0.0), 0.0);
        assert_eq!(relative_difference(1.5, 1.0), 0.5);
        assert_eq!(relative_difference(-1.5, -1.0), -0.5);
        assert_eq!(relative_difference(1.0, 0.0), f64::INFINITY);
    }
}
