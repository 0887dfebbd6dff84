//! PCG32 (O'Neill 2014, "PCG: A Family of Simple Fast Space-Efficient Statistically Good
//! Algorithms for Random Number Generation"): the 64-bit LCG with the XSH-RR output, as
//! `rand_pcg::Pcg32` seeds and steps it, and the same generator in lanes. Every sampler draws
//! its numbers from it, so it is written once over [`crate::simd::Lanes`]: the scalar
//! generator ([`Pcg32`]) is the width-1 instance of the lanes' ([`PcgLanes`]), and the lane
//! engine draws the `independent` sampler's numbers for all its paths at once with the bits
//! the scalar engine draws one path at a time.
//!
//! Its outputs equal `rand_pcg` 0.10's `Pcg32::new(state, stream)` and `random::<f32>()`'s
//! conversion bit for bit (the test below compares them), so images are unchanged by the
//! move from that crate, which keeps its state private.

use crate::simd::{LaneF32, LaneU32, LaneU64, Lanes, Scalar};

/// The LCG's multiplier (Knuth's MMIX).
const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

/// PCG32 streams in lanes: each lane its own state and increment (odd).
#[derive(Clone, Copy, Debug)]
pub struct PcgLanes<L: Lanes> {
    pub state: L::U64,
    pub inc: L::U64,
}

/// One PCG32 stream: the width-1 instance.
pub type Pcg32 = PcgLanes<Scalar>;

impl Pcg32 {
    /// `rand_pcg::Pcg32::new(state, stream)`: increment `2 stream + 1`, then one step from
    /// `state + increment`.
    #[inline]
    pub fn new(state: u64, stream: u64) -> Self {
        let inc = (stream << 1) | 1;
        let state = state
            .wrapping_add(inc)
            .wrapping_mul(MULTIPLIER)
            .wrapping_add(inc);
        PcgLanes { state, inc }
    }

    /// The next 32 random bits.
    #[inline(always)]
    pub fn next_u32(&mut self) -> u32 {
        self.next_u32_lanes(Scalar, true)
    }

    /// Uniform in [0, 1): the top 24 bits of [`Pcg32::next_u32`] times 2⁻²⁴.
    #[inline(always)]
    pub fn next_f32(&mut self) -> f32 {
        self.next_f32_lanes(Scalar, true)
    }
}

impl<L: Lanes> PcgLanes<L> {
    /// Streams in lanes, every lane's state and increment 0 (to be filled lane by lane).
    #[inline(always)]
    pub fn zero(l: L) -> Self {
        let z = l.splat_u64(0);
        PcgLanes { state: z, inc: z }
    }

    /// Lane `i`'s stream.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Pcg32 {
        PcgLanes {
            state: self.state.lane(i),
            inc: self.inc.lane(i),
        }
    }

    /// Lane `i` takes the stream `s`.
    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, s: &Pcg32) {
        self.state.set_lane(i, s.state);
        self.inc.set_lane(i, s.inc);
    }

    /// The next 32 bits of the lanes of `m` (the others keep their state; their value is
    /// unspecified): XSH-RR of the old state, then one LCG step.
    #[inline(always)]
    pub fn next_u32_lanes(&mut self, l: L, m: L::M) -> L::U32 {
        let old = self.state;
        let next = old
            .wrapping_mul(l.splat_u64(MULTIPLIER))
            .wrapping_add(self.inc);
        self.state = L::U64::select(m, next, old);
        let rot = old.shr(59).low32();
        let xsh = (old.shr(18) ^ old).shr(27).low32();
        xsh.rotate_right(rot)
    }

    /// Uniform in [0, 1) in the lanes of `m`: (bits >> 8) · 2⁻²⁴, `rand`'s conversion.
    #[inline(always)]
    pub fn next_f32_lanes(&mut self, l: L, m: L::M) -> L::F {
        let bits = self.next_u32_lanes(l, m);
        // below 2²⁴: exact as an i32 and as an f32
        L::F::from_i32(bits.shr(8)) * l.splat(1.0 / 16_777_216.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, RngExt};

    #[test]
    fn the_scalar_stream_is_rand_pcgs() {
        for (k, (state, stream)) in [
            (0u64, 0u64),
            (1, 1),
            (u64::MAX, u64::MAX),
            (0x853c_49e6_748f_ea9b, 0xda3e_39cb_94b9_5bdb),
        ]
        .into_iter()
        .chain((0..200u64).map(|i| {
            let s = crate::sampler::mix64(i);
            (s, crate::sampler::mix64(s ^ 0x2545_f491_4f6c_dd1d))
        }))
        .enumerate()
        {
            let mut ours = Pcg32::new(state, stream);
            let mut theirs = rand_pcg::Pcg32::new(state, stream);
            for n in 0..64 {
                if n % 2 == 0 {
                    assert_eq!(ours.next_u32(), theirs.next_u32(), "stream {k}, draw {n}");
                } else {
                    let (a, b) = (ours.next_f32(), theirs.random::<f32>());
                    assert_eq!(a.to_bits(), b.to_bits(), "stream {k}, draw {n}");
                }
            }
        }
    }

    /// Every backend draws each lane's numbers with the scalar stream's bits, and a lane
    /// outside the mask keeps its state.
    #[test]
    fn lanes_draw_the_scalar_streams_bits() {
        struct Check;
        impl crate::simd::LaneProgram for Check {
            type Output = ();
            fn run<L: Lanes>(self, l: L) {
                let w = L::WIDTH;
                let mut scalar: Vec<Pcg32> = (0..w as u64)
                    .map(|i| Pcg32::new(crate::sampler::mix64(i + 7), i * 3 + 1))
                    .collect();
                let mut lanes = PcgLanes::zero(l);
                for (i, s) in scalar.iter().enumerate() {
                    lanes.set_lane(i, s);
                }
                for round in 0..40u32 {
                    // a different subset of lanes draws each round
                    let bits = crate::sampler::mix64(round as u64) as u32;
                    let m = l.mask(bits);
                    let f = lanes.next_f32_lanes(l, m);
                    for (i, s) in scalar.iter_mut().enumerate() {
                        if bits >> i & 1 == 1 {
                            let x = s.next_f32();
                            assert_eq!(
                                f.lane(i).to_bits(),
                                x.to_bits(),
                                "{:?} lane {i}",
                                L::BACKEND
                            );
                        }
                        assert_eq!(
                            lanes.lane(i).state,
                            s.state,
                            "{:?} lane {i} round {round}",
                            L::BACKEND
                        );
                    }
                }
            }
        }
        for backend in crate::simd::Backend::all_supported() {
            crate::simd::dispatch(backend, Check);
        }
    }
}
