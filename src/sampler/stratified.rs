//! Mitsuba's `stratified` sampler: jittered stratified sampling (Mitsuba 3.9.1 `stratified`;
//! pbrt-v4 §8.5). A pass of n = r² points puts one point in each of n strata of [0, 1) for
//! a 1D draw and of an r × r grid for a 2D draw; every dimension shuffles the points
//! with its own permutation, so dimensions are independent of each other.
//!
//! | parameter | type | default | |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | rounded up to a square, with a warning |
//! | `seed` | integer | 0 | |
//! | `jitter` | boolean | true | false: the strata's centres (biased; as Mitsuba) |
//!
//! ```xml
//! <sampler type="stratified"><integer name="sample_count" value="64"/></sampler>
//! ```

use super::{permute, sub_seed};
use glam::Vec2;

/// Mitsuba's rounding: the next square.
pub(super) fn round(n: u32) -> u32 {
    let r = side(n);
    r.saturating_mul(r)
}

/// ⌈√n⌉.
pub(super) fn side(n: u32) -> u32 {
    let mut r = (n as f64).sqrt() as u32;
    while (r as u64) * (r as u64) < n as u64 {
        r += 1;
    }
    while r > 1 && ((r - 1) as u64) * ((r - 1) as u64) >= n as u64 {
        r -= 1;
    }
    r
}

/// Point `index` of `n` (1D strata), shuffled by the dimension's seed `h`, at `jitter` within its stratum.
#[inline]
pub(super) fn sample_1d(index: u32, n: u32, h: u64, jitter: f32) -> f32 {
    let s = permute(index, n, sub_seed(h, 0));
    ((s as f32 + jitter) / n as f32).min(ONE_MINUS_EPSILON)
}

/// Point `index` of the √n × √n grid.
#[inline]
pub(super) fn sample_2d(index: u32, n: u32, h: u64, jitter: Vec2) -> Vec2 {
    let r = side(n);
    let s = permute(index, r * r, sub_seed(h, 0));
    let (x, y) = (s % r, s / r);
    ((Vec2::new(x as f32, y as f32) + jitter) / r as f32).min(Vec2::splat(ONE_MINUS_EPSILON))
}

/// The largest f32 below 1: (s + jitter) / n may round up to 1 in f32.
pub(super) const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_stratum_holds_one_point() {
        for n in [1u32, 4, 9, 64] {
            for p in [1u64, 77] {
                let mut hit = vec![0; n as usize];
                let r = side(n);
                let mut hit2 = vec![0; n as usize];
                for i in 0..n {
                    let j = 0.37;
                    let x = sample_1d(i, n, p, j);
                    hit[(x * n as f32) as usize] += 1;
                    let v = sample_2d(i, n, p, Vec2::new(0.9, 0.1));
                    hit2[(v.y * r as f32) as usize * r as usize + (v.x * r as f32) as usize] += 1;
                }
                assert!(hit.iter().all(|&c| c == 1), "n {n}");
                assert!(hit2.iter().all(|&c| c == 1), "n {n}");
            }
        }
    }
}
