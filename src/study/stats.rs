//! Distribution functions for the statistical tests (z-tests of images against references,
//! chi-square goodness-of-fit of samplers), with the Šidák correction for many tests.
//! Formulas: Numerical Recipes (Press et al., 3rd ed.) §6.1–6.2 for ln Γ, the regularised
//! incomplete gamma function and the complementary error function.

/// ln Γ(x) for x > 0 (Lanczos approximation, g = 5, n = 6; relative error < 2e-10).
pub fn ln_gamma(x: f64) -> f64 {
    const COF: [f64; 6] = [
        76.180_091_729_471_46,
        -86.505_320_329_416_77,
        24.014_098_240_830_91,
        -1.231_739_572_450_155,
        0.120_865_097_386_617_9e-2,
        -0.539_523_938_495_3e-5,
    ];
    let mut y = x;
    let tmp = x + 5.5;
    let tmp = tmp - (x + 0.5) * tmp.ln();
    let mut ser = 1.000_000_000_190_015;
    for c in COF {
        y += 1.0;
        ser += c / y;
    }
    -tmp + (2.506_628_274_631_000_5 * ser / x).ln()
}

/// The regularised upper incomplete gamma function Q(a, x) = Γ(a, x) / Γ(a).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    if a <= 0.0 {
        return 0.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        // series for P(a, x)
        let mut ap = a;
        let mut sum = 1.0 / a;
        let mut del = sum;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        // continued fraction for Q(a, x) (modified Lentz)
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// P(χ²_k ≥ x): the p-value of a chi-square statistic with `dof` degrees of freedom.
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    gamma_q(0.5 * dof, 0.5 * x)
}

pub use crate::math::erfc;

/// Two-sided p-value of a standard normal statistic: P(|Z| ≥ |z|).
pub fn normal_two_sided_p(z: f64) -> f64 {
    erfc(z.abs() / std::f64::consts::SQRT_2)
}

/// Šidák-corrected per-test significance level so that `n` independent tests together
/// reject a true null hypothesis with probability `alpha`.
pub fn sidak(alpha: f64, n: usize) -> f64 {
    if n == 0 {
        return alpha;
    }
    // 1 − (1 − α)^(1/n), computed without cancellation.
    -((1.0 - alpha).ln() / n as f64).exp_m1()
}

/// The |z| above which a two-sided test at level `alpha` rejects (bisection on erfc).
pub fn normal_critical_z(alpha: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if normal_two_sided_p(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-9);
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-9);
        // χ² with 2 dof: sf = exp(−x/2)
        for x in [0.1, 1.0, 5.0, 40.0] {
            assert!((chi2_sf(x, 2.0) / (-x / 2.0f64).exp() - 1.0).abs() < 1e-9);
        }
        // tabulated: χ²_{10} at 23.209 has p = 0.01; χ²_{1} at 3.841 has p = 0.05
        assert!((chi2_sf(23.209, 10.0) - 0.01).abs() < 1e-5);
        assert!((chi2_sf(3.841_459, 1.0) - 0.05).abs() < 1e-6);
        assert!((normal_two_sided_p(1.959_964) - 0.05).abs() < 1e-6);
        assert!((normal_critical_z(0.01) - 2.575_829).abs() < 1e-5);
        assert!((normal_two_sided_p(0.0) - 1.0).abs() < 1e-7);
        assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
        let s = sidak(0.01, 196_608);
        assert!((1.0 - (1.0 - s).powf(196_608.0) - 0.01).abs() < 1e-9);
    }
}
