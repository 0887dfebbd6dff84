//! The fit behind the sigmoid-polynomial upsampling table: for an sRGB reflectance, the three
//! coefficients of the spectrum `S(λ) = ½ + ½ x / √(1 + x²)`, `x = c₀λ² + c₁λ + c₂`, whose
//! colour under D65 matches it best in CIELAB (Jakob and Hanika, "A Low-Dimensional Function
//! Space for Efficient Spectral Upsampling", Computer Graphics Forum 38(2), 2019).
//!
//! penumbra's own implementation of the procedure that the paper and its `rgb2spec_opt` tool
//! (the revision Mitsuba 3.9.1 builds its `srgb.coeff` from) describe:
//!
//! - The colour of a spectrum is integrated with composite Simpson's 3/8 rule on 283 points
//!   (three per 5 nm interval) over [360, 830] nm, weighting the CIE 1931 matching functions
//!   by the D65 illuminant (normalised so that a unit reflectance has Y ≈ 1) and converting
//!   to linear sRGB; the CIELAB white point is the colour of the unit reflectance.
//! - The polynomial is fitted in the scaled wavelength `t = (λ − 360) / 470` ∈ [0, 1] (better
//!   conditioned) and converted to nanometres at the end.
//! - The objective is the squared CIELAB distance to the target, minimised by damped
//!   Gauss-Newton (Levenberg-Marquardt) steps with the analytic Jacobian: at most 15 steps,
//!   stopping when the cost falls below 1e-12 or no damping gives a lower cost; damping starts
//!   at 1e-3, is halved after an accepted step and multiplied by 10 after a rejected one.
//! - A table column (fixed largest channel and fixed ratios of the other two to it) is solved
//!   along the brightness axis: from entry `res / 5` upwards, each entry starting from the
//!   previous one's solution, then from `res / 5` downwards, starting again from zero. Where
//!   the colour is reproducible the solution is unique and this order does not matter; where
//!   it is not (saturated colours), the result is where the damped iteration stops, so the
//!   order and starting points decide it; following the same order keeps penumbra close to
//!   Mitsuba's table there too.
//!
//! The arithmetic is double precision throughout (rgb2spec_opt works in single precision):
//! reproducible colours converge to the same coefficients either way.

// Small fixed-size matrix and vector code: indices read as the formulas do.
#![allow(clippy::needless_range_loop)]

use std::sync::LazyLock;

use crate::spectrum::{CIE_SAMPLES, CIE_X, CIE_Y, CIE_Z, D65};

/// Number of quadrature points: three per 5 nm interval, plus the last.
const FINE: usize = (CIE_SAMPLES - 1) * 3 + 1;

/// sRGB (D65) to XYZ and back: the Rec. 709 matrices rgb2spec_opt uses.
const SRGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.412453, 0.357580, 0.180423],
    [0.212671, 0.715160, 0.072169],
    [0.019334, 0.119193, 0.950227],
];
const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.240479, -1.537150, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];

/// The forward model: scaled wavelengths, per-point sRGB weights (matching functions × D65 ×
/// quadrature weight), and the CIELAB white point.
struct Model {
    t: [f64; FINE],
    weights: [[f64; FINE]; 3],
    white: [f64; 3],
}

/// Linear interpolation in a 5 nm table at `lambda` (nm), clamped to the table's ends.
fn interp(table: &[f64; CIE_SAMPLES], lambda: f64) -> f64 {
    let x = (lambda - 360.0) * ((CIE_SAMPLES - 1) as f64 / 470.0);
    let i = (x.max(0.0) as usize).min(CIE_SAMPLES - 2);
    let w = x - i as f64;
    (1.0 - w) * table[i] + w * table[i + 1]
}

/// The normalisation of the D65 table in the paper's reference tables (∫ȳ·D65 over the 5 nm
/// table, so that a unit reflectance has Y ≈ 1).
#[allow(clippy::excessive_precision)]
const D65_SCALE: f64 = 10566.864005283874576;

static MODEL: LazyLock<Model> = LazyLock::new(|| {
    // D65 relative power (the decimal values of the CIE table, recovered exactly from the
    // shortest representation of the f32 entries), scaled so that ∫ȳ·D65 ≈ 1 over the 5 nm
    // table (the constant of the paper's reference tables).
    let d65: [f64; CIE_SAMPLES] =
        D65.map(|v| v.to_string().parse::<f64>().unwrap_or(v as f64) / D65_SCALE);
    let h = 470.0 / (FINE - 1) as f64;
    let mut model = Model {
        t: [0.0; FINE],
        weights: [[0.0; FINE]; 3],
        white: [0.0; 3],
    };
    for i in 0..FINE {
        let lambda = 360.0 + i as f64 * h;
        let xyz = [
            interp(&CIE_X, lambda),
            interp(&CIE_Y, lambda),
            interp(&CIE_Z, lambda),
        ];
        let illuminant = interp(&d65, lambda);
        // Composite Simpson's 3/8: 1, 3, 3, 2, 3, 3, 2, ..., 3, 3, 1 (times 3h/8).
        let weight = 3.0 / 8.0
            * h
            * if i == 0 || i == FINE - 1 {
                1.0
            } else if i % 3 == 0 {
                2.0
            } else {
                3.0
            };
        model.t[i] = (lambda - 360.0) / 470.0;
        for k in 0..3 {
            let rgb: f64 = (0..3).map(|j| XYZ_TO_SRGB[k][j] * xyz[j]).sum();
            model.weights[k][i] = rgb * illuminant * weight;
            model.white[k] += xyz[k] * illuminant * weight;
        }
    }
    model
});

/// CIELAB of a linear sRGB colour (relative to the model's white), and optionally its
/// Jacobian d(Lab)/d(rgb).
fn lab(rgb: [f64; 3], jacobian: Option<&mut [[f64; 3]; 3]>) -> [f64; 3] {
    let white = MODEL.white;
    let delta: f64 = 6.0 / 29.0;
    let mut f = [0.0; 3];
    let mut df = [0.0; 3]; // d f / d XYZ
    for k in 0..3 {
        let xyz: f64 = (0..3).map(|j| SRGB_TO_XYZ[k][j] * rgb[j]).sum();
        let t = xyz / white[k];
        if t > delta * delta * delta {
            let c = t.cbrt();
            f[k] = c;
            df[k] = 1.0 / (3.0 * c * c * white[k]);
        } else {
            f[k] = t / (3.0 * delta * delta) + 4.0 / 29.0;
            df[k] = 1.0 / (3.0 * delta * delta * white[k]);
        }
    }
    if let Some(jac) = jacobian {
        // d Lab / d XYZ, then times d XYZ / d rgb.
        let g = [
            [0.0, 116.0 * df[1], 0.0],
            [500.0 * df[0], -500.0 * df[1], 0.0],
            [0.0, 200.0 * df[1], -200.0 * df[2]],
        ];
        for a in 0..3 {
            for b in 0..3 {
                jac[a][b] = (0..3).map(|k| g[a][k] * SRGB_TO_XYZ[k][b]).sum();
            }
        }
    }
    [
        116.0 * f[1] - 16.0,
        500.0 * (f[0] - f[1]),
        200.0 * (f[1] - f[2]),
    ]
}

/// Residual `Lab(target) − Lab(colour of the spectrum of c)`, and optionally its Jacobian with
/// respect to the (scaled-domain) coefficients.
fn residual(c: [f64; 3], target_lab: [f64; 3], jacobian: Option<&mut [[f64; 3]; 3]>) -> [f64; 3] {
    let m = &*MODEL;
    let mut rgb = [0.0; 3];
    let mut drgb = [[0.0; 3]; 3]; // d rgb[j] / d c[a]
    let want_jacobian = jacobian.is_some();
    for i in 0..FINE {
        let t = m.t[i];
        let x = (c[0] * t + c[1]) * t + c[2];
        let q = 1.0 / (1.0 + x * x).sqrt();
        let s = 0.5 * x * q + 0.5;
        for j in 0..3 {
            rgb[j] += m.weights[j][i] * s;
        }
        if want_jacobian {
            let ds = 0.5 * q * q * q;
            for j in 0..3 {
                let w = m.weights[j][i] * ds;
                drgb[j][0] += w * t * t;
                drgb[j][1] += w * t;
                drgb[j][2] += w;
            }
        }
    }
    let mut lab_jac = [[0.0; 3]; 3];
    let out = lab(rgb, want_jacobian.then_some(&mut lab_jac));
    if let Some(jac) = jacobian {
        for a in 0..3 {
            for b in 0..3 {
                jac[a][b] = -(0..3).map(|k| lab_jac[a][k] * drgb[k][b]).sum::<f64>();
            }
        }
    }
    [0, 1, 2].map(|k| target_lab[k] - out[k])
}

/// Solves the 3×3 system `a x = b` by Gaussian elimination with partial pivoting; `None` when
/// a pivot falls below 1e-30 (degenerate).
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    for col in 0..3 {
        let pivot = (col..3)
            .max_by(|&r, &s| a[r][col].abs().total_cmp(&a[s][col].abs()))
            .unwrap_or(col);
        if a[pivot][col].abs() < 1e-30 || a[pivot][col].is_nan() {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..3 {
            let f = a[row][col] / a[col][col];
            for k in col..3 {
                a[row][k] -= f * a[col][k];
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let s: f64 = (row + 1..3).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    Some(x)
}

fn norm2(r: [f64; 3]) -> f64 {
    r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
}

/// Levenberg-Marquardt on the CIELAB residual, from the scaled-domain coefficients `c`
/// (updated in place). Returns the final CIELAB distance.
pub(crate) fn fit(rgb: [f64; 3], c: &mut [f64; 3]) -> f64 {
    let target = lab(rgb, None);
    let mut jac = [[0.0; 3]; 3];
    let mut res = residual(*c, target, Some(&mut jac));
    let mut cost = norm2(res);
    let mut damping = 1e-3;
    for _ in 0..15 {
        if cost <= 1e-12 {
            break;
        }
        let mut jtj = [[0.0; 3]; 3];
        let mut g = [0.0; 3];
        for a in 0..3 {
            for b in 0..3 {
                jtj[a][b] = (0..3).map(|k| jac[k][a] * jac[k][b]).sum();
            }
            g[a] = (0..3).map(|k| jac[k][a] * res[k]).sum();
        }
        let mut accepted = false;
        for _ in 0..10 {
            let mut m = jtj;
            for (d, row) in m.iter_mut().enumerate() {
                row[d] += damping;
            }
            let Some(step) = solve3(m, g) else {
                damping *= 10.0;
                continue;
            };
            let trial = [c[0] - step[0], c[1] - step[1], c[2] - step[2]];
            let trial_cost = norm2(residual(trial, target, None));
            if trial_cost < cost {
                *c = trial;
                cost = trial_cost;
                damping = (damping * 0.5).max(1e-12);
                accepted = true;
                break;
            }
            damping *= 10.0;
            if damping > 1e12 {
                break;
            }
        }
        if !accepted {
            break;
        }
        res = residual(*c, target, Some(&mut jac));
    }
    cost.sqrt()
}

/// Converts scaled-domain coefficients (polynomial in `(λ − 360) / 470`) to the nanometre
/// domain in which [`srgb_model_eval`](super::srgb_model_eval) evaluates them, rounded to f32.
pub(crate) fn to_nanometres(c: [f64; 3]) -> [f32; 3] {
    let (c0, c1) = (360.0, 1.0 / 470.0);
    [
        (c[0] * c1 * c1) as f32,
        (c[1] * c1 - 2.0 * c[0] * c0 * c1 * c1) as f32,
        (c[2] - c[1] * c0 * c1 + c[0] * (c0 * c1) * (c0 * c1)) as f32,
    ]
}

/// Table resolution along each axis (Mitsuba's `srgb.coeff` is built with 64).
pub const RES: usize = 64;

/// Brightness of table entry `k` on the paper's nonlinear axis: `smoothstep(smoothstep(k /
/// (RES − 1)))`, denser near black and white, rounded to f32 as the table stores it.
pub fn brightness(k: usize) -> f32 {
    let smoothstep = |x: f32| x * x * (3.0 - 2.0 * x);
    smoothstep(smoothstep(k as f32 / (RES - 1) as f32))
}

/// One table column: the coefficients (nm domain) of the `RES` entries whose largest channel
/// is `largest` (0 = r, 1 = g, 2 = b) with brightness [`brightness`]`(k)`, the next channel
/// (cyclically) at `i / (RES − 1)` of it and the one after at `j / (RES − 1)` of it.
pub fn fit_column(largest: usize, j: usize, i: usize) -> [[f32; 3]; RES] {
    let x = i as f32 / (RES - 1) as f32;
    let y = j as f32 / (RES - 1) as f32;
    let target = |k: usize| {
        let b = brightness(k);
        let mut rgb = [0.0; 3];
        rgb[largest] = b as f64;
        rgb[(largest + 1) % 3] = (x * b) as f64;
        rgb[(largest + 2) % 3] = (y * b) as f64;
        rgb
    };
    let mut out = [[0.0; 3]; RES];
    let start = RES / 5;
    let mut c = [0.0; 3];
    for (k, entry) in out.iter_mut().enumerate().skip(start) {
        fit(target(k), &mut c);
        *entry = to_nanometres(c);
    }
    c = [0.0; 3];
    for k in (0..=start).rev() {
        fit(target(k), &mut c);
        out[k] = to_nanometres(c);
    }
    out
}

/// The linear sRGB colour (under D65, by the fit's own quadrature) of the spectrum with
/// scaled-domain coefficients `c`: what the fit matches to the target.
#[cfg(test)]
fn colour_of(c: [f64; 3]) -> [f64; 3] {
    let m = &*MODEL;
    let mut rgb = [0.0; 3];
    for i in 0..FINE {
        let t = m.t[i];
        let x = (c[0] * t + c[1]) * t + c[2];
        let s = 0.5 * x / (1.0 + x * x).sqrt() + 0.5;
        for j in 0..3 {
            rgb[j] += m.weights[j][i] * s;
        }
    }
    rgb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_point_is_unit_luminance_d65() {
        // The unit reflectance under normalised D65 has Y ≈ 1 and sRGB ≈ (1, 1, 1).
        let w = MODEL.white;
        assert!((w[1] - 1.0).abs() < 2e-3, "{w:?}");
        let rgb = colour_of([0.0, 0.0, 1e9]);
        for c in rgb {
            assert!((c - 1.0).abs() < 3e-3, "{rgb:?}");
        }
    }

    #[test]
    fn reproducible_colour_is_reached() {
        let target = [0.3, 0.5, 0.2];
        let mut c = [0.0; 3];
        let dist = fit(target, &mut c);
        assert!(dist < 1e-5, "CIELAB distance {dist}");
        let rgb = colour_of(c);
        for k in 0..3 {
            assert!((rgb[k] - target[k]).abs() < 1e-6, "{rgb:?}");
        }
    }

    #[test]
    fn solve3_solves() {
        let a = [[0.0, 2.0, 1.0], [1.0, 1.0, 0.0], [3.0, 0.0, 1.0]];
        let x = solve3(a, [5.0, 3.0, 6.0]).expect("regular");
        for (r, want) in a.iter().zip([5.0, 3.0, 6.0]) {
            let got: f64 = (0..3).map(|k| r[k] * x[k]).sum();
            assert!((got - want).abs() < 1e-12);
        }
        assert!(solve3([[0.0; 3]; 3], [1.0; 3]).is_none());
    }
}
