//! Mitsuba's `orthogonal` sampler: orthogonal-array-based Latin hypercubes (Jarosz, Enayet,
//! Kensler, Kilpatrick and Christensen, "Orthogonal Array Sampling for Monte Carlo
//! Rendering", EGSR 2019). Row i of an orthogonal array OA(n = r^t, ·, r, t) gives sample i
//! a stratum in every dimension such that any t dimensions together are stratified on an
//! r^t grid (t = `strength`); within its stratum a point takes a shuffled sub-stratum and
//! a jitter ("multi-jittered" flavour), so each dimension alone is a Latin hypercube. Strength
//! 2 uses the Bose construction, others the Bush construction (polynomials over GF(r), r
//! prime). Every draw, 1D or 2D, is one column of the array per dimension, as in Mitsuba.
//!
//! | parameter | type | default | |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | rounded up to the square of a prime, with a warning |
//! | `seed` | integer | 0 | |
//! | `strength` | integer | 2 | 2 to 8 |
//! | `jitter` | boolean | true | |
//!
//! ```xml
//! <sampler type="orthogonal"><integer name="sample_count" value="121"/></sampler>
//! ```
//!
//! Unlike the other samplers, the shuffle of the sample index is shared by all dimensions
//! of a pixel (the array's rows tie them together); each dimension permutes its own
//! symbols, which keeps every point uniform on its own.

use super::stratified::ONE_MINUS_EPSILON;
use super::{mix64, permute, sub_seed};

fn is_prime(x: u32) -> bool {
    x >= 2
        && (2..)
            .take_while(|i| i * i <= x)
            .all(|i| !x.is_multiple_of(i))
}

/// Mitsuba's array side for `n` points: the smallest prime r ≥ 2 with r² ≥ n.
pub(super) fn resolution(n: u32) -> u32 {
    let mut r = 2u32;
    while (r as u64 * r as u64) < n as u64 || !is_prime(r) {
        r += 1;
    }
    r
}

/// The rows of the array a pass uses: strength 2, all r² rows of the Bose array; Bush, r²
/// of the r^t rows (as many whole digits as fit a 32-bit index).
fn rows(r: u32, strength: u32) -> (u32, u32) {
    if strength == 2 {
        return (r * r, 2);
    }
    let mut t = strength;
    while (r as u64)
        .checked_pow(t)
        .is_none_or(|b| b > u32::MAX as u64)
        && t > 2
    {
        t -= 1;
    }
    ((r as u64).pow(t).min(u32::MAX as u64) as u32, t)
}

/// The array row of sample `index` of a pass on the r × r grid, shuffled by the pixel's pass
/// seed `p`: the same row for all dimensions of the sample.
pub(super) fn row(index: u32, r: u32, strength: u32, p: u32) -> u32 {
    let (count, _) = rows(r, strength);
    permute(index % (r * r), count, p)
}

/// Dimension `j` (a column of the array) of the sample on `row`.
pub(super) fn sample(row: u32, r: u32, strength: u32, j: u32, p: u32, jitter: f32) -> f32 {
    let h = mix64(((p as u64) << 32) | j as u64);
    let (r64, j64) = (r as u64, j as u64);
    let (stratum, sub, subs) = if strength == 2 {
        // Bose: rows (a0, a1) of the r × r grid; column j is a0 + (j − 1) a1 mod r, the
        // first two columns a0 and a1; the sub-stratum is the partner column's symbol.
        let (a0, a1) = ((row / r) as u64, (row % r) as u64);
        let column = |c: u64| match c {
            0 => a0,
            1 => a1,
            _ => (a0 + (c - 1) % r64 * a1) % r64,
        };
        let partner = if j64 % 2 == 1 { j64 - 1 } else { j64 + 1 };
        (column(j64), column(partner), r)
    } else {
        // Bush: the row's base-r digits are the coefficients of a polynomial evaluated at j
        // in GF(r); the sub-stratum is the row's remaining digits.
        let (count, t) = rows(r, strength);
        let x = j64 % r64;
        let mut digits = [0u64; 8];
        let mut rest = row as u64;
        for d in digits.iter_mut().take(t as usize) {
            *d = rest % r64;
            rest /= r64;
        }
        let phi = digits[..t as usize]
            .iter()
            .rev()
            .fold(0u64, |acc, &c| (acc * x + c) % r64);
        let subs = count / r;
        (phi, (row / r % subs) as u64, subs)
    };
    let stratum = permute(stratum as u32, r, sub_seed(h, 1));
    let sub = permute(sub as u32, subs, sub_seed(h, 2));
    ((stratum as f32 + (sub as f32 + jitter) / subs as f32) / r as f32).min(ONE_MINUS_EPSILON)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Strength 2: every pair of the array's r + 1 columns is stratified on the r × r grid,
    /// and every dimension alone is a Latin hypercube (one point per 1/n interval).
    #[test]
    fn bose_pairs_are_stratified() {
        for n in [4u32, 9, 25, 49] {
            let r = resolution(n);
            let dims = r + 1;
            let pts: Vec<Vec<f32>> = (0..n)
                .map(|i| {
                    (0..dims)
                        .map(|j| sample(row(i, r, 2, 99), r, 2, j, 99, 0.5))
                        .collect()
                })
                .collect();
            for a in 0..dims as usize {
                let mut latin = vec![0; n as usize];
                for p in &pts {
                    latin[(p[a] * n as f32) as usize] += 1;
                }
                assert!(latin.iter().all(|&c| c == 1), "n {n} dim {a}");
                for b in a + 1..dims as usize {
                    let mut cell = vec![0; n as usize];
                    for p in &pts {
                        let (x, y) = ((p[a] * r as f32) as usize, (p[b] * r as f32) as usize);
                        cell[y * r as usize + x] += 1;
                    }
                    assert!(cell.iter().all(|&c| c == 1), "n {n} dims {a},{b}");
                }
            }
        }
    }

    /// Strength 3 with the full r³ rows: every triple of dimensions is stratified on r³.
    #[test]
    fn bush_triples_are_stratified() {
        let r = 3u32;
        let big = r * r * r;
        let dims = 3;
        let pts: Vec<Vec<f32>> = (0..big)
            .map(|i| {
                (0..dims)
                    .map(|j| sample(permute(i, big, 5), r, 3, j, 5, 0.5))
                    .collect()
            })
            .collect();
        let mut cell = vec![0; big as usize];
        for p in &pts {
            let c: Vec<usize> = p.iter().map(|&v| (v * r as f32) as usize).collect();
            cell[(c[2] * r as usize + c[1]) * r as usize + c[0]] += 1;
        }
        assert!(cell.iter().all(|&c| c == 1), "{cell:?}");
    }

    #[test]
    fn primes() {
        let p: Vec<u32> = (0..20).filter(|&x| is_prime(x)).collect();
        assert_eq!(p, [2, 3, 5, 7, 11, 13, 17, 19]);
    }
}
