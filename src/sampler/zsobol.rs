//! `zsobol` (penumbra's; Mitsuba has no such plugin): Owen-scrambled Sobol points in
//! Morton order, after pbrt-v4's `ZSobolSampler` (Ahmed and Wonka, "Screen-Space Blue-Noise
//! Diffusion of Monte Carlo Sampling Error via Hierarchical Ordering of Pixels", SIGGRAPH
//! Asia 2020) with Burley's hash-based Owen scrambling ("Practical Hash-based Owen
//! Scrambling", JCGT 2020).
//!
//! The image's samples are one sequence: pixel (x, y) owns the indices whose high digits are
//! its Morton code, and its n = 2^k samples the low k bits. Per dimension, the base-4 digits
//! of that index are permuted by a hash of the digits above them, so the pixels' point sets
//! are distinct blocks of the sequence, spread over the image as blue noise. Each draw uses
//! the first two Sobol dimensions (the (0,2)-sequence) of its index, padded: every dimension
//! has its own digit permutation and its own nested uniform (Owen) scramble. A pixel's first
//! 2^j samples are a (0, j, 2)-net for every j ≤ k with k − j even (every power of four when
//! k is even), so a render continued at those counts stays a net.
//!
//! | parameter | type | default | |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | rounded up to a power of two, with a warning |
//! | `seed` | integer | 0 | |
//!
//! ```xml
//! <sampler type="zsobol"><integer name="sample_count" value="64"/></sampler>
//! ```

use super::ldsampler::sobol_2;
use super::{mix64, sub_seed, unit};
use glam::Vec2;

/// The pixel's place in the image's sequence.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Pixel {
    /// Morton code of the pixel, followed by the k bits of the sample index.
    morton: u64,
    /// k = log2 of the samples per pass.
    log2_spp: u32,
    /// Base-4 digits of `morton` that get permuted.
    base4_digits: u32,
}

fn morton2(x: u32, y: u32) -> u64 {
    let spread = |v: u32| {
        let mut v = v as u64 & 0xffff_ffff;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    };
    spread(x) | (spread(y) << 1)
}

/// Sample `index` of pixel (x, y) in an image whose larger side is `side`, n = 2^k per pass.
pub(super) fn pixel(x: u32, y: u32, side: u32, n: u32, index: u32) -> Pixel {
    let log2_spp = n.max(1).trailing_zeros();
    let log2_res = side.max(1).next_power_of_two().trailing_zeros();
    Pixel {
        morton: (morton2(x, y) << log2_spp) | index as u64,
        log2_spp,
        base4_digits: log2_res + log2_spp.div_ceil(2),
    }
}

/// The hash that picks a digit's permutation: SplitMix64's finaliser (pbrt-v4 uses its
/// MixBits, the same kind: a weaker one-round mixer correlated neighbouring pixels).
#[inline]
fn digit_hash(x: u64) -> u64 {
    mix64(x) >> 24
}

/// The 24 permutations of (0, 1, 2, 3), in lexicographic order.
const PERMUTATIONS: [[u8; 4]; 24] = {
    let mut out = [[0u8; 4]; 24];
    let mut k = 0;
    let mut a = 0;
    while a < 4 {
        let mut b = 0;
        while b < 4 {
            let mut c = 0;
            while c < 4 {
                if a != b && a != c && b != c {
                    out[k] = [a, b, c, 6 - a - b - c];
                    k += 1;
                }
                c += 1;
            }
            b += 1;
        }
        a += 1;
    }
    out
};

impl Pixel {
    /// The sequence index this sample uses in dimension `dim`: each base-4 digit permuted
    /// by a hash of the digits above it (an odd k leaves one base-2 digit at the bottom).
    fn index(&self, dim: u32) -> u64 {
        let odd = self.log2_spp & 1;
        let salt = 0x5555_5555u64.wrapping_mul(dim as u64);
        let mut out = 0u64;
        for i in (odd..self.base4_digits).rev() {
            let shift = 2 * i - odd;
            let digit = (self.morton >> shift) & 3;
            let higher = self.morton >> (shift + 2);
            let p = (digit_hash(higher ^ salt) % 24) as usize;
            out |= (PERMUTATIONS[p][digit as usize] as u64) << shift;
        }
        if odd == 1 {
            let digit = self.morton & 1;
            out |= digit ^ (digit_hash((self.morton >> 1) ^ salt) & 1);
        }
        out
    }
}

/// Nested uniform scrambling of a 32-bit fraction, by Burley's Laine–Karras-style hash.
#[inline]
fn owen_scramble(v: u32, seed: u32) -> u32 {
    let mut x = v.reverse_bits();
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x.reverse_bits()
}

/// The scramble seed of dimension `dim`'s k-th coordinate; indices beyond 32 bits (images
/// with more than 2^32 samples per pass) get other seeds instead of repeating points.
#[inline]
fn seed(h: u64, index: u64, k: u64) -> u32 {
    sub_seed(h ^ mix64(index >> 32), k)
}

#[inline]
pub(super) fn sample_1d(px: Pixel, dim: u32, p: u64) -> f32 {
    let i = px.index(dim);
    unit(owen_scramble((i as u32).reverse_bits(), seed(p, i, 1)))
}

#[inline]
pub(super) fn sample_2d(px: Pixel, dim: u32, p: u64) -> Vec2 {
    let i = px.index(dim);
    Vec2::new(
        unit(owen_scramble((i as u32).reverse_bits(), seed(p, i, 2))),
        unit(owen_scramble(sobol_2(i as u32), seed(p, i, 3))),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn net(pts: &[Vec2], m: u32) -> bool {
        (0..=m).all(|a| {
            let (gx, gy) = (1usize << a, 1usize << (m - a));
            let mut cell = vec![0; 1 << m];
            for v in pts {
                cell[(v.y * gy as f32) as usize * gx + (v.x * gx as f32) as usize] += 1;
            }
            cell.iter().all(|&c| c == 1)
        })
    }

    /// Every pixel's pass is a (0, k, 2)-net, and so is its first 2^j samples for j ≤ k
    /// with k − j even (the digit permutations act on base-4 digits).
    #[test]
    fn pixels_and_prefixes_are_nets() {
        for k in [2u32, 3, 6] {
            let n = 1 << k;
            for (x, y) in [(0, 0), (5, 3), (31, 17)] {
                for dim in [0u32, 1, 7] {
                    let pts: Vec<Vec2> = (0..n)
                        .map(|i| sample_2d(pixel(x, y, 40, n, i), dim, 99))
                        .collect();
                    for j in (0..=k).filter(|j| (k - j) % 2 == 0) {
                        assert!(
                            net(&pts[..1 << j], j),
                            "k {k} pixel {x},{y} dim {dim} prefix 2^{j}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn permutations_are_distinct() {
        for (i, p) in PERMUTATIONS.iter().enumerate() {
            let mut s = *p;
            s.sort();
            assert_eq!(s, [0, 1, 2, 3]);
            assert!(PERMUTATIONS[..i].iter().all(|q| q != p));
        }
    }
}
