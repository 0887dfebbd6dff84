//! Samplers: the numbers a pixel sample draws, dimension by dimension.
//!
//! | plugin | points per pass (Mitsuba's `sample_count` rounding) | model |
//! |---|---|---|
//! | `independent` | any | uniform PCG32 numbers (O'Neill 2014) |
//! | `stratified` (`jitter`) | the next square | jittered strata, 1D and 2D, shuffled per dimension |
//! | `multijitter` (`jitter`) | rx·ry, ry = ⌊√n⌋ | correlated multi-jittered (Kensler 2013) |
//! | `orthogonal` (`strength`, `jitter`) | the next square of a prime | orthogonal-array Latin hypercubes (Jarosz et al. 2019), Bose (strength 2) or Bush |
//! | `ldsampler` | the next square of a power of two | scrambled (0,2)-sequence (Kollig and Keller 2002), shuffled per dimension |
//! | `zsobol` (penumbra's) | the next power of two | Owen-scrambled Sobol points (Burley 2020) in pbrt-v4's Morton ("ZSobol") order |
//!
//! **Determinism.** The numbers of a pixel sample depend only on (seed, pixel, sample index,
//! dimension), so an image is bit-identical at any thread count and tile order, and a render
//! can be continued, resumed or split into parts. Every sampler draws its jitter from the
//! same PCG32 stream as `independent`, keyed by (seed, pixel, sample index).
//!
//! **Passes.** The stratified samplers need their point count `n` up front: sample index
//! `s` is point `s mod n` of pass `⌊s / n⌋`, and every pass is a fresh, independently
//! shuffled and scrambled point set. A render of a multiple of `n` samples is therefore
//! fully stratified in every pass; a render extended by another `n` adds a second
//! stratified set. A partial pass is unbiased (each point is still uniform on its own), only
//! less stratified. `independent` has no passes; `zsobol`'s first 4^j points of a pass of
//! 4^k are themselves a (0, 2j, 2)-net, so its ladders can continue a render at every power
//! of four.
//!
//! **Unbiasedness.** Each point is uniform and its dimensions are independent of each other
//! (every dimension has its own permutation and scramble). Mitsuba 3.9.1's `ldsampler`
//! shares one scramble across all dimensions of a pixel, which ties the low digits of
//! different dimensions together and biases renders (0.45% low on a diffuse Cornell box);
//! penumbra's draws a scramble per dimension.

mod ldsampler;
mod multijitter;
mod orthogonal;
pub mod pcg;
mod stratified;
mod zsobol;

use crate::simd::{for_each_lane, LaneF32, Lanes};
use glam::Vec2;
use pcg::{Pcg32, PcgLanes};

/// SplitMix64's finaliser (Steele et al. 2014): a bijective 64-bit mixer.
#[inline]
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A 32-bit hash of two values.
#[inline]
fn hash32(a: u64, b: u64) -> u32 {
    (mix64(mix64(a ^ 0x6a09_e667_f3bc_c909) ^ b) >> 32) as u32
}

/// The `k`-th 32-bit seed drawn from a well-mixed 64-bit hash `h` (one multiply: the seeds
/// of one dimension's permutations and scrambles).
#[inline]
fn sub_seed(h: u64, k: u64) -> u32 {
    ((h ^ k.wrapping_mul(0x9e37_79b9_7f4a_7c15)).wrapping_mul(0xd6e8_feb8_6659_fd93) >> 32) as u32
}

/// A pseudo-random permutation of `0..n` indexed by `seed`: Kensler's hash-based
/// permutation ("Correlated Multi-Jittered Sampling", Pixar 2013), cycle-walking to `n`.
#[inline]
pub(crate) fn permute(mut i: u32, n: u32, p: u32) -> u32 {
    if n <= 1 {
        return 0;
    }
    let mut w = n - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i ^= p;
        i = i.wrapping_mul(0xe170_893d);
        i ^= p >> 16;
        i ^= (i & w) >> 4;
        i ^= p >> 8;
        i = i.wrapping_mul(0x0929_eb3f);
        i ^= p >> 23;
        i ^= (i & w) >> 1;
        i = i.wrapping_mul(1 | p >> 27);
        i = i.wrapping_mul(0x6935_fa69);
        i ^= (i & w) >> 11;
        i = i.wrapping_mul(0x74dc_b303);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0x9e50_1cc3);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0xc860_a3df);
        i &= w;
        i ^= i >> 5;
        if i < n {
            break;
        }
    }
    (i.wrapping_add(p)) % n
}

/// A 32-bit fixed-point fraction as an `f32` in [0, 1) (the top 24 bits: never rounds to 1).
#[inline]
fn unit(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The sampler plugin and its parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SamplerKind {
    #[default]
    Independent,
    Stratified {
        jitter: bool,
    },
    Multijitter {
        jitter: bool,
    },
    Orthogonal {
        strength: u32,
        jitter: bool,
    },
    LdSampler,
    ZSobol,
}

impl SamplerKind {
    /// The plugin name, as in a scene file.
    pub fn name(&self) -> &'static str {
        match self {
            SamplerKind::Independent => "independent",
            SamplerKind::Stratified { .. } => "stratified",
            SamplerKind::Multijitter { .. } => "multijitter",
            SamplerKind::Orthogonal { .. } => "orthogonal",
            SamplerKind::LdSampler => "ldsampler",
            SamplerKind::ZSobol => "zsobol",
        }
    }

    /// The plugin named `name` with its default parameters.
    pub fn from_name(name: &str) -> Option<SamplerKind> {
        Some(match name {
            "independent" => SamplerKind::Independent,
            "stratified" => SamplerKind::Stratified { jitter: true },
            "multijitter" => SamplerKind::Multijitter { jitter: true },
            "orthogonal" => SamplerKind::Orthogonal {
                strength: 2,
                jitter: true,
            },
            "ldsampler" => SamplerKind::LdSampler,
            "zsobol" => SamplerKind::ZSobol,
            _ => return None,
        })
    }

    /// The point count the sampler uses for `requested` samples per pixel: Mitsuba's
    /// `set_sample_count` rounding (zsobol: the next power of two, as pbrt-v4's).
    pub fn round_sample_count(&self, requested: u32) -> u32 {
        let n = requested.max(1);
        match self {
            SamplerKind::Independent => n,
            SamplerKind::Stratified { .. } => stratified::round(n),
            SamplerKind::Multijitter { .. } => {
                let (rx, ry) = multijitter::resolution(n);
                rx.saturating_mul(ry)
            }
            SamplerKind::Orthogonal { .. } => {
                let r = orthogonal::resolution(n);
                r.saturating_mul(r)
            }
            SamplerKind::LdSampler => ldsampler::round(n),
            SamplerKind::ZSobol => n.checked_next_power_of_two().unwrap_or(1 << 31),
        }
    }

    /// Whether the first k points of a pass are as good as a fresh render at k (independent
    /// points, and zsobol's nets at powers of four), so that a convergence ladder may
    /// continue one render; the others render each ladder step afresh.
    pub fn progressive(&self) -> bool {
        matches!(self, SamplerKind::Independent | SamplerKind::ZSobol)
    }
}

/// A sampler ready to draw: the plugin and its point count per pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sampler {
    pub kind: SamplerKind,
    /// Points per pass, already rounded ([`SamplerKind::round_sample_count`]).
    pub sample_count: u32,
}

impl Sampler {
    /// The sampler for `requested` samples per pixel, and a warning when the plugin's
    /// rounding changes the count (as Mitsuba warns).
    pub fn new(kind: SamplerKind, requested: u32) -> (Sampler, Option<String>) {
        let sample_count = kind.round_sample_count(requested);
        let warning = (sample_count != requested).then(|| {
            format!(
                "the {} sampler rounds sample_count {requested} to {sample_count}",
                kind.name()
            )
        });
        (Sampler { kind, sample_count }, warning)
    }

    pub fn independent() -> Sampler {
        Sampler {
            kind: SamplerKind::Independent,
            sample_count: 1,
        }
    }

    /// The numbers of sample `sample` of pixel (x, y) of a `width` x `height` image.
    pub fn stream(
        &self,
        seed: u64,
        (x, y): (u32, u32),
        (width, height): (u32, u32),
        sample: u64,
    ) -> SampleStream {
        let pixel = y as u64 * width as u64 + x as u64;
        let mut s = SampleStream::new(seed, pixel, sample);
        if self.kind == SamplerKind::Independent {
            return s;
        }
        let n = self.sample_count.max(1) as u64;
        let (pass, index) = (sample / n, (sample % n) as u32);
        s.kind = self.kind;
        s.n = n as u32;
        s.index = index;
        s.seq_seed = match self.kind {
            // zsobol decorrelates pixels by its Morton order, not by a per-pixel seed
            SamplerKind::ZSobol => {
                s.zsobol = zsobol::pixel(x, y, width.max(height), n as u32, index);
                hash32(seed ^ 0x5a50_b01d, pass)
            }
            _ => hash32(mix64(seed) ^ pixel, pass),
        };
        if let SamplerKind::Orthogonal { strength, .. } = self.kind {
            // the array's row, shared by all dimensions of the sample
            let r = stratified::side(s.n);
            s.index = orthogonal::row(s.index, r, strength, s.seq_seed);
        }
        s
    }
}

/// The random numbers of one pixel sample.
pub struct SampleStream {
    rng: Pcg32,
    kind: SamplerKind,
    /// Points per pass.
    n: u32,
    /// This sample's point in its pass (orthogonal: its row of the array).
    index: u32,
    /// Seed of this pixel's pass (zsobol: of the whole image's pass).
    seq_seed: u32,
    /// The next dimension.
    dim: u32,
    /// zsobol: the pixel's place in the image's sequence.
    zsobol: zsobol::Pixel,
}

impl SampleStream {
    /// An `independent` stream for (seed, pixel, sample).
    pub fn new(seed: u64, pixel: u64, sample: u64) -> Self {
        let key = mix64(mix64(mix64(seed ^ 0x9e37_79b9_7f4a_7c15) ^ pixel) ^ sample);
        let stream = mix64(key ^ 0x2545_f491_4f6c_dd1d);
        SampleStream {
            rng: Pcg32::new(key, stream),
            kind: SamplerKind::Independent,
            n: 1,
            index: 0,
            seq_seed: 0,
            dim: 0,
            zsobol: zsobol::Pixel::default(),
        }
    }

    /// The `independent` sampler's generator, at this stream's next draw (`None` for the
    /// other samplers, whose draws depend on more than the generator): what the lane
    /// engine draws from in lanes ([`Draws::Independent`]).
    pub fn independent_pcg(&self) -> Option<Pcg32> {
        matches!(self.kind, SamplerKind::Independent).then_some(self.rng)
    }

    /// A uniform jitter in [0, 1), or the stratum's centre without jitter.
    #[inline]
    fn jitter(&mut self, on: bool) -> f32 {
        if on {
            self.rng.next_f32()
        } else {
            0.5
        }
    }

    /// The next dimension and its 64-bit seed.
    #[inline]
    fn next_dimension(&mut self) -> (u32, u64) {
        let d = self.dim;
        self.dim += 1;
        (d, mix64(((self.seq_seed as u64) << 32) | d as u64))
    }

    /// Uniform in [0, 1). The `independent` sampler's draw is inlined at the call; the
    /// others go through [`SampleStream::next_1d_structured`] (one call that matched on
    /// every kind was not inlined: 34 instructions per draw, 4% of a Cornell box render).
    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        if matches!(self.kind, SamplerKind::Independent) {
            self.rng.next_f32()
        } else {
            self.next_1d_structured()
        }
    }

    #[inline(never)]
    fn next_1d_structured(&mut self) -> f32 {
        match self.kind {
            SamplerKind::Independent => self.rng.next_f32(),
            SamplerKind::Stratified { jitter } => {
                let (_, p) = self.next_dimension();
                let j = self.jitter(jitter);
                stratified::sample_1d(self.index, self.n, p, j)
            }
            SamplerKind::Multijitter { jitter } => {
                let (_, p) = self.next_dimension();
                let j = self.jitter(jitter);
                stratified::sample_1d(self.index, self.n, p, j)
            }
            SamplerKind::Orthogonal { strength, jitter } => {
                let (d, _) = self.next_dimension();
                let j = self.jitter(jitter);
                let r = stratified::side(self.n);
                orthogonal::sample(self.index, r, strength, d, self.seq_seed, j)
            }
            SamplerKind::LdSampler => {
                let (_, p) = self.next_dimension();
                ldsampler::sample_1d(self.index, self.n, p)
            }
            SamplerKind::ZSobol => {
                let (d, h) = self.next_dimension();
                zsobol::sample_1d(self.zsobol, d, h)
            }
        }
    }

    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        if matches!(self.kind, SamplerKind::Independent) {
            let x = self.next_1d();
            Vec2::new(x, self.next_1d())
        } else {
            self.next_2d_structured()
        }
    }

    #[inline(never)]
    fn next_2d_structured(&mut self) -> Vec2 {
        match self.kind {
            SamplerKind::Independent => {
                let x = self.next_1d();
                Vec2::new(x, self.next_1d())
            }
            SamplerKind::Stratified { jitter } => {
                let (_, p) = self.next_dimension();
                let j = Vec2::new(self.jitter(jitter), self.jitter(jitter));
                stratified::sample_2d(self.index, self.n, p, j)
            }
            SamplerKind::Multijitter { jitter } => {
                let (_, p) = self.next_dimension();
                let j = Vec2::new(self.jitter(jitter), self.jitter(jitter));
                multijitter::sample_2d(self.index, self.n, p, j)
            }
            // Mitsuba's orthogonal sampler: two 1D draws (two columns of the array)
            SamplerKind::Orthogonal { .. } => {
                let x = self.next_1d();
                Vec2::new(x, self.next_1d())
            }
            SamplerKind::LdSampler => {
                let (_, p) = self.next_dimension();
                ldsampler::sample_2d(self.index, self.n, p)
            }
            SamplerKind::ZSobol => {
                let (d, h) = self.next_dimension();
                zsobol::sample_2d(self.zsobol, d, h)
            }
        }
    }
}

/// Where the paths in lanes draw their numbers, lane `i` its own sample's: from its
/// [`SampleStream`] one lane at a time (any sampler), or, for the `independent` sampler,
/// from every lane's PCG32 at once in lanes (the same numbers: its draws are the
/// generator's, [`SampleStream::independent_pcg`]).
pub enum Draws<'a, L: Lanes> {
    Streams(&'a mut [SampleStream]),
    Independent(&'a mut PcgLanes<L>),
}

impl<L: Lanes> Draws<'_, L> {
    /// [`SampleStream::next_1d`] of the lanes of `m` (other lanes: unspecified).
    #[inline(always)]
    pub fn next_1d(&mut self, l: L, m: L::M) -> L::F {
        match self {
            Draws::Independent(pcg) => pcg.next_f32_lanes(l, m),
            Draws::Streams(streams) => {
                let mut u = l.splat(0.0);
                for_each_lane(L::WIDTH, m, |i| u.set_lane(i, streams[i].next_1d()));
                u
            }
        }
    }

    /// [`SampleStream::next_2d`] of the lanes of `m` (other lanes: unspecified).
    #[inline(always)]
    pub fn next_2d(&mut self, l: L, m: L::M) -> (L::F, L::F) {
        match self {
            Draws::Independent(pcg) => {
                let x = pcg.next_f32_lanes(l, m);
                (x, pcg.next_f32_lanes(l, m))
            }
            Draws::Streams(streams) => {
                let (mut x, mut y) = (l.splat(0.0), l.splat(0.0));
                for_each_lane(L::WIDTH, m, |i| {
                    let u = streams[i].next_2d();
                    x.set_lane(i, u.x);
                    y.set_lane(i, u.y);
                });
                (x, y)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<f32> = (0..8)
            .map({
                let mut s = SampleStream::new(1, 2, 3);
                move |_| s.next_1d()
            })
            .collect();
        let mut s = SampleStream::new(1, 2, 3);
        assert!(a.iter().all(|&x| x == s.next_1d()));
        for (seed, px, smp) in [(2, 2, 3), (1, 3, 3), (1, 2, 4)] {
            let mut t = SampleStream::new(seed, px, smp);
            assert_ne!(a[0], t.next_1d());
        }
    }

    #[test]
    fn uniform_mean_and_range() {
        let mut sum = 0.0f64;
        let n = 100_000;
        for i in 0..n {
            let x = SampleStream::new(7, i, 0).next_1d();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        // mean of U(0,1): sd of the mean is 1/sqrt(12 n) ≈ 9.1e-4; 5 sigma.
        assert!((sum / n as f64 - 0.5).abs() < 5.0 * 9.2e-4);
    }

    #[test]
    fn kensler_permutation_is_a_permutation() {
        for n in [1u32, 2, 3, 5, 16, 17, 100, 1024] {
            for p in [0u32, 1, 0xdead_beef] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let j = permute(i, n, p);
                    assert!(j < n && !seen[j as usize], "n {n} p {p} i {i}");
                    seen[j as usize] = true;
                }
            }
        }
    }

    #[test]
    fn rounding_follows_mitsuba() {
        let r = |k: &str, n| SamplerKind::from_name(k).unwrap().round_sample_count(n);
        // Mitsuba 3.9.1's set_sample_count for each plugin
        assert_eq!(
            [r("independent", 5), r("stratified", 5), r("stratified", 16)],
            [5, 9, 16]
        );
        assert_eq!(
            [
                r("multijitter", 5),
                r("multijitter", 10),
                r("multijitter", 16)
            ],
            [6, 12, 16]
        );
        assert_eq!(
            [r("orthogonal", 5), r("orthogonal", 16), r("orthogonal", 64)],
            [9, 25, 121]
        );
        assert_eq!(
            [r("ldsampler", 5), r("ldsampler", 16), r("ldsampler", 17)],
            [16, 16, 64]
        );
        assert_eq!([r("zsobol", 5), r("zsobol", 64)], [8, 64]);
        assert_eq!(r("ldsampler", 1), 4);
    }
}
