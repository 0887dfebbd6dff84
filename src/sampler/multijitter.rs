//! Mitsuba's `multijitter` sampler: correlated multi-jittered sampling (Kensler,
//! "Correlated Multi-Jittered Sampling", Pixar technical memo 13-01, 2013). A 2D draw of a
//! pass of n = rx · ry points is stratified on the rx × ry grid and, within it, a Latin
//! hypercube (one point in each of the n columns and n rows); 1D draws are stratified as in
//! `stratified`. Every dimension has its own shuffle.
//!
//! | parameter | type | default | |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | rounded up to rx · ry with ry = ⌊√n⌋, with a warning |
//! | `seed` | integer | 0 | |
//! | `jitter` | boolean | true | |
//!
//! ```xml
//! <sampler type="multijitter"><integer name="sample_count" value="64"/></sampler>
//! ```

use super::stratified::ONE_MINUS_EPSILON;
use super::{permute, sub_seed};
use glam::Vec2;

/// Mitsuba's grid for `n` points: ry = ⌊√n⌋, rx = ⌈n / ry⌉ (the same for the rounded n).
pub(super) fn resolution(n: u32) -> (u32, u32) {
    let mut ry = (n as f64).sqrt() as u32;
    while (ry as u64 + 1) * (ry as u64 + 1) <= n as u64 {
        ry += 1;
    }
    while ry as u64 * ry as u64 > n as u64 {
        ry -= 1;
    }
    let ry = ry.max(1);
    (n.div_ceil(ry), ry)
}

/// Point `index` of the pass, shuffled by the dimension's seed `h`.
#[inline]
pub(super) fn sample_2d(index: u32, n: u32, h: u64, jitter: Vec2) -> Vec2 {
    let (rx, ry) = resolution(n);
    let s = permute(index, rx * ry, sub_seed(h, 0));
    let (x, y) = (s % rx, s / rx);
    // the sub-stratum of a column is a shuffle of its row, and the other way round
    let sx = permute(x, rx, sub_seed(h, 1));
    let sy = permute(y, ry, sub_seed(h, 2));
    Vec2::new(
        (x as f32 + (sy as f32 + jitter.x) / ry as f32) / rx as f32,
        (y as f32 + (sx as f32 + jitter.y) / rx as f32) / ry as f32,
    )
    .min(Vec2::splat(ONE_MINUS_EPSILON))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One point per cell of the rx × ry grid, and per column and row of the fine n × n grid.
    #[test]
    fn stratified_and_latin_hypercube() {
        for n in [4u32, 6, 12, 64] {
            let (rx, ry) = resolution(n);
            assert_eq!(rx * ry, n);
            let mut cell = vec![0; n as usize];
            let (mut col, mut row) = (vec![0; n as usize], vec![0; n as usize]);
            for i in 0..n {
                let v = sample_2d(i, n, 12345, Vec2::new(0.3, 0.8));
                cell[(v.y * ry as f32) as usize * rx as usize + (v.x * rx as f32) as usize] += 1;
                col[(v.x * n as f32) as usize] += 1;
                row[(v.y * n as f32) as usize] += 1;
            }
            assert!(cell.iter().all(|&c| c == 1), "cells, n {n}");
            assert!(col.iter().chain(&row).all(|&c| c == 1), "latin, n {n}");
        }
    }
}
