#!/usr/bin/env python3
"""Fits the polynomial coefficients of penumbra's elementary functions (src/math/elementary.rs).

Each function is reduced to a short interval and written as a leading term plus a correction
g(z), z the reduced argument or its square; g is fitted in 60-digit arithmetic by mpmath's
Chebyshev fit (least squares on Chebyshev nodes, within a small factor of the minimax error),
then rounded to f64. The script prints each fit's degree, its error bound on g and the
coefficients in Horner order (highest degree first), as the Rust source lists them.

    python3 validation/math/fit_coefficients.py
"""
from mpmath import mp, mpf, sin, cos, exp, atan, asin, log, sqrt, pi, chebyfit, atanh

mp.dps = 60


def fit(name, g, a, b, degree):
    poly, err = chebyfit(g, [mpf(a), mpf(b)], degree + 1, error=True)
    print(f"{name}: degree {degree} on [{mp.nstr(mpf(a), 6)}, {mp.nstr(mpf(b), 6)}], |err| <= {mp.nstr(err, 3)}")
    for c in poly:
        print(f"    {float(c)!r},")
    return poly


def series_safe(f, z0):
    """f(z), with the removable singularity at 0 taken from z0 (a tiny positive z)."""
    return lambda z: f(z if z != 0 else mpf(z0))


if __name__ == "__main__":
    q = (pi / 4) ** 2
    # sin r = r + r z S(z), z = r^2, |r| <= pi/4
    S = series_safe(lambda z: (sin(sqrt(z)) / sqrt(z) - 1) / z, "1e-40")
    # cos r = 1 - z/2 + z^2 C(z)
    C = series_safe(lambda z: (cos(sqrt(z)) - 1 + z / 2) / z**2, "1e-30")
    # f32 results (evaluated in f64): degree 3; f64 results: degree 5
    for deg in (3, 5):
        fit("sin S(z)", S, 0, q, deg)
        fit("cos C(z)", C, 0, q, deg)
    # exp r = 1 + r + r^2/2 + r^3 E(r), |r| <= ln2/2
    h = log(2) / 2
    # (by its series: the closed form cancels near r = 0)
    E = lambda r: sum(r**k / mp.factorial(k + 3) for k in range(60))
    for deg in (9, 10):
        fit("exp E(r)", E, -h, h, deg)
    # ln(1+f) = 2 atanh(s), s = f/(2+f), |s| <= (sqrt2-1)/(sqrt2+1): R(z) = z L(z), z = s^2
    smax = (sqrt(2) - 1) / (sqrt(2) + 1)
    L = series_safe(lambda z: (2 * atanh(sqrt(z)) / sqrt(z) - 2) / z, "1e-40")
    for deg in (6,):
        fit("ln L(z)", L, 0, smax**2, deg)
    # atan t = t + t z A(z), z = t^2, |t| <= 7/16
    A = series_safe(lambda z: (atan(sqrt(z)) / sqrt(z) - 1) / z, "1e-40")
    for deg in (11,):
        fit("atan A(z)", A, 0, (mpf(7) / 16) ** 2, deg)
    # asin s = s + s z P(z), z = s^2, |s| <= 1/2
    P = series_safe(lambda z: (asin(sqrt(z)) / sqrt(z) - 1) / z, "1e-40")
    for deg in (12,):
        fit("asin P(z)", P, 0, mpf(1) / 4, deg)
