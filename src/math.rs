//! Numerical building blocks shared by the renderer and the study: the complementary error
//! function, a first guess of the inverse error function, and quadrature rules (composite
//! Simpson, Gauss–Legendre); and in [`elementary`], penumbra's own sine, cosine, exp, ln,
//! atan2 and acos, which every per-sample caller uses instead of the platform's libm.

mod elementary;
pub use elementary::{acos, acosf, atan2, atan2f, exp, expf, ln, lnf, sin_cos, sin_cosf};
pub(crate) use elementary::{sin_cosf_f64, F64Ops, SIN_COS_LIMIT_F32};

/// The complementary error function (Chebyshev fit, relative error < 1.2e-7 everywhere).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let ans = t * exp(poly);
    if x >= 0.0 {
        ans
    } else {
        2.0 - ans
    }
}

/// ∫ₐᵇ f by the composite Simpson rule on `n` (even) intervals: (h/3) [f(a) + f(b) +
/// Σ 4 f(odd nodes) + Σ 2 f(even inner nodes)], summed in that order.
pub fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let mut acc = f(a) + f(b);
    for k in 1..n {
        acc += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    acc * h / 3.0
}

/// A first guess of erf⁻¹(y) for Newton iterations: Giles's form (2010, "Approximating the
/// erfinv function", GPU Computing Gems, Jade Edition, ch. 10), erf⁻¹(y) = y p(w) with
/// w = −ln(1 − y²) and p a polynomial of degree 8 in w − 2.5 (w < 5) or √w − 3 (w ≥ 5), with
/// coefficients fitted for penumbra by least squares in f64 against erf⁻¹ from Newton's
/// method on `libm`'s erf. Relative error below 5e-7 for |y| ≤ 0.9966 (w < 5) and 3e-6 up to
/// |y| = 1 − 1e-12.
pub fn erfinv_approx(y: f64) -> f64 {
    let w = -ln((1.0 - y) * (1.0 + y));
    let (w, coefficients) = if w < 5.0 {
        (
            w - 2.5,
            [
                2.293_776_920e-8,
                3.496_567_580e-7,
                -3.459_431_552e-6,
                -4.452_791_099e-6,
                2.183_333_281e-4,
                -1.253_561_607e-3,
                -4.177_375_071e-3,
                2.466_406_363e-1,
                1.501_409_357,
            ],
        )
    } else {
        (
            w.sqrt() - 3.0,
            [
                2.683_479_057e-5,
                -2.851_352_701e-4,
                1.288_861_161e-3,
                -3.314_018_412e-3,
                5.665_738_302e-3,
                -7.718_132_258e-3,
                9.462_820_449e-3,
                1.001_680_713,
                2.832_976_082,
            ],
        )
    };
    coefficients.iter().fold(0.0, |p, c| c + p * w) * y
}

/// The nodes and weights of the n-point Gauss–Legendre rule on [−1, 1] (exact for
/// polynomials of degree 2n − 1): the nodes are the roots of the Legendre polynomial Pₙ, found
/// by Newton's method from Tricomi's initial guesses, and wᵢ = 2 / ((1 − xᵢ²) Pₙ′(xᵢ)²)
/// (Abramowitz and Stegun 25.4.29). In f64; n ≥ 1. (The `gauss-quad` crate would bring
/// nalgebra along for this.)
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let n = n.max(1);
    let (mut nodes, mut weights) = (vec![0.0; n], vec![0.0; n]);
    // Pₙ(x) and Pₙ′(x) by the three-term recurrence.
    let legendre = |x: f64| {
        let (mut p0, mut p1) = (1.0, x);
        for k in 2..=n {
            let k = k as f64;
            let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
            p0 = p1;
            p1 = p2;
        }
        let p = if n == 1 { x } else { p1 };
        let prev = if n == 1 { 1.0 } else { p0 };
        (p, n as f64 * (x * p - prev) / (x * x - 1.0))
    };
    for i in 0..n.div_ceil(2) {
        let nf = n as f64;
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        for _ in 0..100 {
            let (p, dp) = legendre(x);
            let dx = p / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let (_, dp) = legendre(x);
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = -x;
        nodes[n - 1 - i] = x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    if n % 2 == 1 {
        nodes[n / 2] = 0.0;
    }
    (nodes, weights)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against tabulated values of erf⁻¹ (to 1e-6 relative) and, over (−1, 1) up to
    /// 1 − 1e-12, against erfc: a relative error ε in x = erf⁻¹(y) moves erfc(x) by about
    /// (2x² + 1) ε relative, so with ε ≤ 3e-6 and erfc's own 1.2e-7, erfc(x) = 1 − y to
    /// (2x² + 1) · 3e-6 + 2e-7.
    #[test]
    fn erfinv_approx_inverts_erf() {
        for (y, want) in [
            (0.5, 0.476_936_276_204_469_9),
            (0.9, 1.163_087_153_676_674_3),
            (0.99, 1.821_386_367_718_449_6),
            (0.999, 2.326_753_765_513_524_6),
        ] {
            for (y, want) in [(y, want), (-y, -want)] {
                let got = erfinv_approx(y);
                assert!(
                    (got - want).abs() <= 1e-6 * want.abs(),
                    "{y}: {got} vs {want}"
                );
            }
        }
        for k in 1..=1200 {
            let y = if k <= 1000 {
                k as f64 / 1001.0
            } else {
                1.0 - 10f64.powf(-3.0 - 9.0 * (k - 1000) as f64 / 200.0)
            };
            let x = erfinv_approx(y);
            let bound = (2.0 * x * x + 1.0) * 3e-6 + 2e-7;
            let err = ((erfc(x) - (1.0 - y)) / (1.0 - y)).abs();
            assert!(err <= bound, "y = {y}: x = {x}, erfc off by {err:e}");
            assert_eq!(erfinv_approx(-y), -x);
        }
    }

    /// Against tabulated rules (Abramowitz and Stegun, Table 25.4) and polynomial exactness.
    #[test]
    fn gauss_legendre_rules() {
        let (x, w) = gauss_legendre(3);
        assert!((x[2] - 0.774_596_669_241_483).abs() < 1e-14 && x[1].abs() < 1e-15);
        assert!((w[0] - 5.0 / 9.0).abs() < 1e-14 && (w[1] - 8.0 / 9.0).abs() < 1e-14);
        let (x, w) = gauss_legendre(4);
        assert!((x[3] - 0.861_136_311_594_053).abs() < 1e-14);
        assert!((w[3] - 0.347_854_845_137_454).abs() < 1e-14);
        for n in [1, 2, 5, 32, 128] {
            let (x, w) = gauss_legendre(n);
            for degree in 0..2 * n {
                let exact = if degree % 2 == 1 {
                    0.0
                } else {
                    2.0 / (degree + 1) as f64
                };
                let sum: f64 = x
                    .iter()
                    .zip(&w)
                    .map(|(x, w)| w * x.powi(degree as i32))
                    .sum();
                assert!((sum - exact).abs() < 1e-12, "n {n}, degree {degree}: {sum}");
            }
        }
    }
}
