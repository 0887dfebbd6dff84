//! Numerical building blocks shared by the renderer and the study: the complementary error
//! function and Gauss–Legendre quadrature rules.

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
    let ans = t * poly.exp();
    if x >= 0.0 {
        ans
    } else {
        2.0 - ans
    }
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
