//! The exact film at any scale (issue 40): passes are summed exactly and canonically over the
//! whole f64 range, so that a render's result does not depend on the absolute scale of its
//! radiance, nor on how its passes are grouped (parts, merges, resumes), in the image or in
//! the stored state's bytes.
//!
//! The accumulator is checked against an independent oracle written here: a dense
//! fixed-point integer in units of 2⁻¹⁰⁷⁴ wide enough for any sum of the test's terms, and a
//! check of correct rounding that only compares exact distances to the candidate and its two
//! neighbouring doubles. The scene-level tests render the Cornell box with its emitter scaled
//! by powers of two (exact through every f32 product while nothing underflows: the images
//! must be the unit image times the factor, bit for bit) and by issue 40's literal factors.

mod common;

use common::*;
use penumbra::film::{ExactFilm, ExactSum, Film, FilmTile, Filter, EXACT_VALUES};
use penumbra::progressive::{
    merge_part_files, merge_parts, relative_standard_error, render_part, render_progressive,
    Checkpoint, ErrorTarget, PartPlan, ProgressiveSettings, StopReason,
};
use penumbra::render::Job;
use penumbra::render::RenderSettings;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------
// A counting allocator: live and peak bytes of the current thread (for the streaming merge).

struct Counting;

thread_local! {
    static LIVE: Cell<i64> = const { Cell::new(0) };
    static PEAK: Cell<i64> = const { Cell::new(0) };
}

fn note(delta: i64) {
    // try_with: the thread-locals may be gone while a thread exits.
    let _ = LIVE.try_with(|l| {
        let v = l.get() + delta;
        l.set(v);
        let _ = PEAK.try_with(|p| p.set(p.get().max(v)));
    });
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size() as i64);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        note(-(layout.size() as i64));
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size() as i64);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size as i64 - layout.size() as i64);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The peak of live bytes on this thread while `f` runs, above what was live before.
fn peak_bytes_of<T>(f: impl FnOnce() -> T) -> (T, i64) {
    let before = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(before));
    let out = f();
    (out, PEAK.with(Cell::get) - before)
}

// ---------------------------------------------------------------------------------------
// A small deterministic generator (SplitMix64).

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            v.swap(i, self.below(i + 1));
        }
    }
    /// A finite double with a random sign and mantissa, its biased exponent uniform in
    /// `exps` (0 is the subnormals): log-uniform over that range of binades.
    fn double(&mut self, exps: std::ops::Range<u64>) -> f64 {
        let exp = exps.start + self.next() % (exps.end - exps.start);
        let frac = self.next() >> 12;
        let sign = self.next() & 1;
        f64::from_bits(sign << 63 | exp << 52 | frac)
    }
}

// ---------------------------------------------------------------------------------------
// The oracle: a dense two's-complement integer in units of 2^-1074.

const LIMBS: usize = 40; // 2560 bits: ±2^1024 · 2^1074 · 2^400 of headroom

#[derive(Clone, PartialEq, Eq, Debug)]
struct Dense([u64; LIMBS]);

impl Dense {
    fn zero() -> Self {
        Dense([0; LIMBS])
    }
    /// m · 2^shift, in units of 2^-1074 (shift ≥ 0).
    fn from_u128(m: u128, shift: usize) -> Self {
        let mut d = Dense::zero();
        for b in 0..128 {
            if m >> b & 1 == 1 {
                let p = b + shift;
                d.0[p / 64] |= 1 << (p % 64);
            }
        }
        d
    }
    fn from_f64(x: f64) -> Self {
        assert!(x.is_finite());
        let bits = x.to_bits();
        let exp = (bits >> 52 & 0x7ff) as usize;
        let frac = bits & ((1 << 52) - 1);
        let (mant, shift) = if exp == 0 {
            (frac, 0)
        } else {
            (frac | 1 << 52, exp - 1)
        };
        let d = Dense::from_u128(mant as u128, shift);
        if bits >> 63 == 1 {
            d.neg()
        } else {
            d
        }
    }
    fn add(&self, o: &Dense) -> Dense {
        let mut r = Dense::zero();
        let mut carry = 0u64;
        for i in 0..LIMBS {
            let (s1, c1) = self.0[i].overflowing_add(o.0[i]);
            let (s2, c2) = s1.overflowing_add(carry);
            r.0[i] = s2;
            carry = (c1 | c2) as u64;
        }
        r
    }
    fn neg(&self) -> Dense {
        let mut r = Dense(self.0.map(|l| !l));
        for l in r.0.iter_mut() {
            let (s, c) = l.overflowing_add(1);
            *l = s;
            if !c {
                break;
            }
        }
        r
    }
    fn sub(&self, o: &Dense) -> Dense {
        self.add(&o.neg())
    }
    fn negative(&self) -> bool {
        (self.0[LIMBS - 1] as i64) < 0
    }
    fn abs(&self) -> Dense {
        if self.negative() {
            self.neg()
        } else {
            self.clone()
        }
    }
    /// Unsigned comparison of magnitudes (both non-negative).
    fn cmp_mag(&self, o: &Dense) -> std::cmp::Ordering {
        for i in (0..LIMBS).rev() {
            match self.0[i].cmp(&o.0[i]) {
                std::cmp::Ordering::Equal => {}
                c => return c,
            }
        }
        std::cmp::Ordering::Equal
    }
    /// An accumulator's exact value, from its magnitude limbs.
    fn of_sum(s: &ExactSum) -> Dense {
        let (neg, mag, exp) = s.to_magnitude();
        let mut d = Dense::zero();
        for (i, l) in mag.iter().enumerate() {
            for b in 0..64 {
                if l >> b & 1 == 1 {
                    let p = exp + 64 * i as i64 + b as i64 + 1074;
                    assert!(
                        p >= 0 && (p as usize) < 64 * LIMBS - 1,
                        "bit {p} out of range"
                    );
                    d.0[p as usize / 64] |= 1 << (p % 64);
                }
            }
        }
        if neg {
            d.neg()
        } else {
            d
        }
    }
}

/// `r` is the exact sum `s` rounded to the nearest double, ties to even, ±∞ from
/// 2^1024 − 2^970 on: checked by comparing exact distances to r and its two neighbours.
fn assert_correctly_rounded(s: &Dense, r: f64, what: &str) {
    let overflow = Dense::from_u128((1u128 << 54) - 1, 970 + 1074);
    if r.is_infinite() {
        assert!(
            s.abs().cmp_mag(&overflow).is_ge() && s.negative() == (r < 0.0),
            "{what}: {r} but the sum is finite"
        );
        return;
    }
    let d = s.sub(&Dense::from_f64(r)).abs();
    for n in [r.next_up(), r.next_down()] {
        if n.is_infinite() {
            assert!(
                s.abs().cmp_mag(&overflow).is_lt(),
                "{what}: {r} but the sum overflows"
            );
            continue;
        }
        let dn = s.sub(&Dense::from_f64(n)).abs();
        match d.cmp_mag(&dn) {
            std::cmp::Ordering::Less => {}
            std::cmp::Ordering::Equal => assert!(
                r.to_bits() & 1 == 0 || r == 0.0,
                "{what}: a tie between {r} and {n} went to the odd one"
            ),
            std::cmp::Ordering::Greater => panic!("{what}: {n} is nearer the exact sum than {r}"),
        }
    }
}

/// The sum of `terms` added one after another.
fn sequential(terms: &[f64], bits: u32) -> ExactSum {
    let mut s = ExactSum::with_inline_bits(bits);
    for &t in terms {
        s.add_f64(t).expect("finite");
    }
    s
}

/// The sum of `terms` over a random binary merge tree: split at a random point, sum each
/// side (recursively, or sequentially for small runs), add the two exact sums.
fn tree(terms: &[f64], bits: u32, rng: &mut Rng) -> ExactSum {
    if terms.len() <= 2 || rng.below(4) == 0 {
        return sequential(terms, bits);
    }
    let at = 1 + rng.below(terms.len() - 1);
    let mut left = tree(&terms[..at], bits, rng);
    let right = tree(&terms[at..], bits, rng);
    left.add(&right);
    left
}

/// Random multisets: terms over the whole range, over 40 binades, at unit scale, and
/// cancellation sets.
fn multisets() -> Vec<Vec<f64>> {
    let mut rng = Rng(40);
    let mut sets = Vec::new();
    for case in 0..300 {
        let n = 1 + rng.below(40);
        let mut v: Vec<f64> = (0..n)
            .map(|_| match case % 3 {
                0 => rng.double(0..2047),          // every binade, subnormals included
                1 => rng.double(1003..1043),       // 40 binades around 1
                _ => rng.double(1021..1025).abs(), // unit-scale, positive (a pixel's sums)
            })
            .collect();
        // Cancellation: x, −x pairs and the issue's 1e300, 1, −1e300.
        if case % 5 == 0 {
            let x = v[0];
            v.push(-x);
            v.extend([1e300, 1.0, -1e300]);
        }
        // Ties: x and half its ulp (either sign), so that the exact sum lies halfway
        // between two doubles.
        if case % 4 == 1 {
            let x = v[0];
            let half_ulp = (x.next_up() - x) / 2.0;
            if half_ulp != 0.0 {
                v.push(if rng.below(2) == 0 {
                    half_ulp
                } else {
                    -half_ulp
                });
            }
        }
        if case % 7 == 0 {
            v.extend([f64::MAX, f64::MAX, -f64::MAX, f64::from_bits(1), -5e-324]);
        }
        sets.push(v);
    }
    sets.push(vec![1e300, 1.0, -1e300]);
    sets.push(vec![1e300, -1e300]);
    sets.push(vec![0.1, 0.2, 0.3]);
    sets.push(vec![f64::from_bits(1); 3]);
    // Ties to even at 1, in the subnormals and at the overflow threshold 2^1024 − 2^970.
    sets.push(vec![1.0, 2f64.powi(-53)]);
    sets.push(vec![1.0, 3.0 * 2f64.powi(-53)]);
    sets.push(vec![f64::MAX, 2f64.powi(970)]);
    sets.push(vec![f64::MAX, 2f64.powi(969)]);
    sets.push(vec![-f64::MAX, -2f64.powi(970), 2f64.powi(-1074)]);
    sets
}

/// Any permutation and any merge tree of the same terms gives the same state bytes, and the
/// exact value and its read-out agree with the oracle: at the film's inline capacity (125
/// bits) and at capacities of 4 and 53 bits, where nearly every sum spills.
#[test]
fn accumulator_is_exact_and_canonical_in_any_order_and_merge_tree() {
    let mut rng = Rng(7);
    // (spilled, inline) at 125 and at 4 bits.
    let mut paths = [[0usize; 2]; 2];
    for (i, terms) in multisets().iter().enumerate() {
        let exact = terms
            .iter()
            .fold(Dense::zero(), |s, &t| s.add(&Dense::from_f64(t)));
        let mut readouts = Vec::new();
        for bits in [125, 53, 4] {
            let reference = sequential(terms, bits);
            let what = format!("set {i} ({} terms), {bits}-bit inline", terms.len());
            assert_eq!(Dense::of_sum(&reference), exact, "{what}: exact value");
            assert_correctly_rounded(&exact, reference.to_f64(), &what);
            readouts.push(reference.to_f64().to_bits());
            if bits != 53 {
                paths[(bits == 4) as usize][(!reference.is_spilled()) as usize] += 1;
            }
            for trial in 0..6 {
                let mut p = terms.clone();
                rng.shuffle(&mut p);
                let s = if trial % 2 == 0 {
                    sequential(&p, bits)
                } else {
                    tree(&p, bits, &mut rng)
                };
                assert_eq!(
                    s.state_bytes(),
                    reference.state_bytes(),
                    "{what}: trial {trial} gives other state bytes"
                );
            }
        }
        assert!(
            readouts.windows(2).all(|w| w[0] == w[1]),
            "set {i}: read-outs differ with the capacity"
        );
    }
    // Both paths are exercised at the film's capacity, and at 4 bits nearly every sum
    // spills (the rest are 0 or a few bits wide).
    eprintln!(
        "(spilled, inline) at 125 bits {:?}, at 4 bits {:?}",
        paths[0], paths[1]
    );
    assert!(paths[0][0] > 20 && paths[0][1] > 20, "{paths:?}");
    assert!(paths[1][0] > 9 * paths[1][1], "{paths:?}");
}

/// One sample of 1e30 (as f32) among 10⁶ unit samples: every sum is exact (Σf and Σf²
/// against the oracle), Σf² spills (its span is about 200 bits), nothing is refused.
#[test]
fn a_firefly_among_a_million_unit_samples_accumulates_exactly() {
    let firefly = 1e30f32;
    let mut exact = ExactFilm::new(1, 1);
    // 1000 passes of 1000 unit samples (each pass's f64 sums exact), then the firefly's pass.
    let pass_of = |v: f32, n: usize| {
        let mut tile = FilmTile::new(0, 0, 1, 1, Filter::Box);
        for _ in 0..n {
            tile.add_sample(glam::Vec2::new(0.5, 0.5), glam::Vec3::splat(v));
        }
        let mut film = Film::new(1, 1, Filter::Box);
        film.merge(&tile);
        film
    };
    let unit = pass_of(1.0, 1000);
    for _ in 0..1000 {
        exact.add(&unit).expect("adds");
    }
    exact
        .add(&pass_of(firefly, 1))
        .expect("the firefly's pass adds");
    let f = firefly as f64;
    let want_sum = Dense::from_f64(f).add(&Dense::from_f64(1e6));
    let want_sq = Dense::from_f64(f * f).add(&Dense::from_f64(1e6));
    assert_eq!(
        f * f,
        (firefly as f64).powi(2),
        "the square is exact in f64"
    );
    for c in 0..3 {
        assert_eq!(
            Dense::of_sum(&exact.value(0, c)),
            want_sum,
            "Σf, channel {c}"
        );
        assert_eq!(
            Dense::of_sum(&exact.value(0, 3 + c)),
            want_sq,
            "Σf², channel {c}"
        );
        assert!(
            exact.value(0, 3 + c).is_spilled(),
            "Σf² spans ~200 bits: spilled"
        );
    }
    assert_eq!(
        Dense::of_sum(&exact.value(0, 12)),
        Dense::from_f64(1e6 + 1.0)
    );
    let film = exact.to_film(Filter::Box);
    assert_correctly_rounded(&want_sum, film.sum[0][0], "Σf read-out");
    assert_correctly_rounded(&want_sq, film.sum_sq[0][0], "Σf² read-out");
    assert_eq!(film.samples, 1_000_001);
    // Reading the unit samples back: subtracting the firefly exactly leaves 10⁶.
    let mut rest = exact.value(0, 0);
    rest.add_f64(-f).expect("finite");
    assert_eq!(rest.to_f64(), 1e6);
}

/// A sample at f32's limit (3e38) accumulates: its square, 9e76, is far beyond the old fixed
/// point's 2⁷⁸, and every sum comes back exactly.
#[test]
fn a_sample_at_the_f32_limit_accumulates() {
    let v = 3e38f32;
    let mut tile = FilmTile::new(0, 0, 2, 1, Filter::Box);
    tile.add_sample(glam::Vec2::new(0.5, 0.5), glam::Vec3::new(v, f32::MAX, 1.0));
    tile.add_sample(glam::Vec2::new(1.5, 0.5), glam::Vec3::splat(1e-30));
    let mut pass = Film::new(2, 1, Filter::Box);
    pass.merge(&tile);
    let mut exact = ExactFilm::new(2, 1);
    for _ in 0..3 {
        exact.add(&pass).expect("an f32-limit sample accumulates");
    }
    let film = exact.to_film(Filter::Box);
    assert_eq!(film.sum[0], [3.0 * v as f64, 3.0 * f32::MAX as f64, 3.0]);
    assert_eq!(film.sum_sq[0][0], 3.0 * (v as f64 * v as f64));
    assert_eq!(film.image()[0], [v, f32::MAX, 1.0]);
    assert_eq!(film.image()[1], [1e-30; 3]);
    assert_eq!(film.sum_sq[1][0], 3.0 * (1e-30f32 as f64).powi(2));
}

/// Films with a 4-bit inline capacity (nearly every sum spills) hold the same exact sums as
/// the default films: the same read-out, bit for bit, through adds, merges and a state
/// round trip; and each capacity's state bytes are the same for any grouping.
#[test]
fn films_that_spill_nearly_everything_give_the_same_sums() {
    let mut rng = Rng(11);
    let (w, h) = (7, 5);
    let passes: Vec<Film> = (0..6)
        .map(|k| {
            let mut f = Film::new(w, h, Filter::Box);
            for i in 0..w * h {
                let mut d = || match k % 3 {
                    0 => rng.double(1003..1043),
                    1 => rng.double(900..1100),
                    _ => rng.double(1..2046),
                };
                f.sum[i] = [d(), d(), d()];
                f.sum_sq[i] = [d(), d(), d()];
                f.sum_w2[i] = [d(), d(), d()];
                f.sum_sq_w2[i] = [d(), d(), d()];
                f.weight[i] = d();
                f.weight_sq[i] = d();
                f.weight_cube[i] = d();
            }
            f.samples = 3;
            f
        })
        .collect();
    let bits_of = |f: &Film| {
        let mut v = Vec::new();
        for i in 0..w * h {
            for c in 0..3 {
                v.extend([
                    f.sum[i][c],
                    f.sum_sq[i][c],
                    f.sum_w2[i][c],
                    f.sum_sq_w2[i][c],
                ]);
            }
            v.extend([f.weight[i], f.weight_sq[i], f.weight_cube[i]]);
        }
        v.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    };
    let mut images = Vec::new();
    for bits in [125u32, 4] {
        let mut seq = ExactFilm::with_inline_bits(w, h, bits);
        for p in &passes {
            seq.add(p).expect("adds");
        }
        // Another grouping: two halves in reverse order, merged.
        let (mut a, mut b) = (
            ExactFilm::with_inline_bits(w, h, bits),
            ExactFilm::with_inline_bits(w, h, bits),
        );
        for p in passes[..3].iter().rev() {
            a.add(p).expect("adds");
        }
        for p in passes[3..].iter().rev() {
            b.add(p).expect("adds");
        }
        b.add_exact(&a).expect("merges");
        assert_eq!(seq.state_bytes(), b.state_bytes(), "{bits}-bit: grouping");
        let state = seq.state_bytes();
        let (back, used) = ExactFilm::read_state(&state, w, h, seq.samples).expect("reads");
        assert_eq!(used, state.len());
        assert_eq!(back, seq, "{bits}-bit: state round trip");
        if bits == 4 {
            assert!(
                seq.spilled() > w * h * EXACT_VALUES * 9 / 10,
                "{}",
                seq.spilled()
            );
        }
        images.push(bits_of(&seq.to_film(Filter::Box)));
        // Every value against the oracle.
        for i in 0..w * h {
            let sums: Vec<f64> = passes.iter().map(|p| p.sum_sq_w2[i][1]).collect();
            let want = sums
                .iter()
                .fold(Dense::zero(), |s, &t| s.add(&Dense::from_f64(t)));
            assert_eq!(Dense::of_sum(&seq.value(i, 10)), want);
        }
    }
    assert!(
        images[0] == images[1],
        "the read-outs differ with the capacity"
    );
}

/// A state that is not canonical, or whose sizes do not match its length, is one clear error;
/// random corruptions never panic, and what reads back writes the same bytes.
#[test]
fn corrupt_states_are_refused_without_panic() {
    let mut rng = Rng(3);
    let mut exact = ExactFilm::new(3, 2);
    let mut pass = Film::new(3, 2, Filter::Box);
    for i in 0..6 {
        pass.sum[i] = [1.0, 1e30, 3e-300];
        pass.sum_sq[i] = [1.0, 1e60, 0.0];
        pass.weight[i] = 1.0;
    }
    exact.add(&pass).expect("adds");
    pass.sum[0] = [1e-30, 1.0, 1.0];
    exact.add(&pass).expect("adds");
    assert!(exact.spilled() > 0);
    let state = exact.state_bytes();
    let err = |b: &[u8], w, h| {
        ExactFilm::read_state(b, w, h, 0)
            .map(|_| ())
            .expect_err("refused")
            .to_string()
    };
    // Sizes: a resolution the bytes do not hold, and an overflowing one.
    assert!(err(&state, 3000, 2000).contains("shorter than its resolution"));
    assert!(err(&state, usize::MAX, 3).contains("resolution"));
    assert!(err(&state[..state.len() - 3], 3, 2).contains("truncated"));
    // An even mantissa (not canonical) and an exponent below 2^-1074.
    let mut b = state.clone();
    b[1] = 2;
    b[2..17].fill(0);
    let e_at = 1 + 6 * EXACT_VALUES * 16;
    b[e_at..e_at + 2].copy_from_slice(&0i16.to_le_bytes());
    assert!(err(&b, 3, 2).contains("not canonical"));
    let mut b = state.clone();
    b[1..17].copy_from_slice(&1i128.to_le_bytes());
    b[e_at..e_at + 2].copy_from_slice(&(-2000i16).to_le_bytes());
    assert!(err(&b, 3, 2).contains("out of range"));
    // A huge spill count.
    let mut b = state.clone();
    let count_at = 1 + 6 * EXACT_VALUES * 18;
    b[count_at..count_at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(err(&b, 3, 2).contains("spill count"));
    // Random corruptions: Ok (then canonical: writes back the same bytes) or Err.
    for _ in 0..3000 {
        let mut b = state.clone();
        for _ in 0..1 + rng.below(3) {
            let at = rng.below(b.len());
            b[at] ^= 1 << rng.below(8);
        }
        if let Ok((f, used)) = ExactFilm::read_state(&b, 3, 2, 0) {
            assert_eq!(
                f.state_bytes(),
                b[..used],
                "a corrupt state read as another"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// Scene level.

const SEED: u64 = 21;

fn settings(spp: u32) -> ProgressiveSettings {
    ProgressiveSettings {
        spp,
        seed: SEED,
        threads: None,
        time_limit: None,
        target_rel_error: None,
        checkpoint: None,
        scene_hash: 0,
        stop: None,
    }
}

const CORNELL_RADIANCE: &str = r#"<rgb name="radiance" value="18.387, 13.9873, 6.75357"/>"#;

/// The Cornell box at `res`² with its emitter's radiance multiplied by `factor` (in f64, then
/// written with enough digits to read back the same double: exact for a power of two).
fn cornell_scaled(res: u32, factor: Option<f64>) -> Job {
    let path = repo_path("scenes/cornell-box.xml");
    let text = std::fs::read_to_string(&path).expect("scene");
    assert_eq!(
        text.matches(CORNELL_RADIANCE).count(),
        1,
        "the emitter's radiance"
    );
    let text = match factor {
        None => text,
        Some(s) => {
            let v = [18.387f64, 13.9873, 6.75357].map(|x| format!("{:e}", x * s));
            text.replace(
                CORNELL_RADIANCE,
                &format!(
                    r#"<rgb name="radiance" value="{}, {}, {}"/>"#,
                    v[0], v[1], v[2]
                ),
            )
        }
    };
    let defines = [("res".to_string(), res.to_string())];
    Job::from_xml_str(&text, &path, &defines).expect("scene builds")
}

/// The Cornell box with its emitter written with a literal factor, as issue 40's scenes are:
/// each radiance rounds once (to f64 here, then to f32 in the scene).
fn cornell_literal(res: u32, exponent: i32) -> Job {
    let path = repo_path("scenes/cornell-box.xml");
    let text = std::fs::read_to_string(&path).expect("scene");
    let text = text.replace(
        CORNELL_RADIANCE,
        &format!(
            r#"<rgb name="radiance" value="18.387e{exponent}, 13.9873e{exponent}, 6.75357e{exponent}"/>"#
        ),
    );
    let defines = [("res".to_string(), res.to_string())];
    Job::from_xml_str(&text, &path, &defines).expect("scene builds")
}

fn progressive_film(scene: &Job, spp: u32) -> Film {
    let (p, reason) = render_progressive(scene, &settings(spp), None, &|_| {}).expect("renders");
    assert_eq!(reason, StopReason::SppReached);
    p.film
}

/// Every sum of `scaled` is that of `unit` times the factor (Σf, Σw²f) or its square (Σf²,
/// Σw²f²), bit for bit; weights equal; image and variance (f64) scaled bit for bit.
fn assert_scaled_bitwise(unit: &Film, scaled: &Film, s: f64, what: &str) {
    let s2 = s * s;
    assert_eq!(unit.samples, scaled.samples);
    let (su, ss) = (unit.spp(), scaled.spp());
    let mut lit = 0;
    for i in 0..unit.sum.len() {
        for c in 0..3 {
            let pairs = [
                (unit.sum[i][c] * s, scaled.sum[i][c], "Σf"),
                (unit.sum_sq[i][c] * s2, scaled.sum_sq[i][c], "Σf²"),
                (unit.sum_w2[i][c] * s, scaled.sum_w2[i][c], "Σw²f"),
                (unit.sum_sq_w2[i][c] * s2, scaled.sum_sq_w2[i][c], "Σw²f²"),
                (unit.mean_f64(i)[c] * s, scaled.mean_f64(i)[c], "mean"),
                (
                    unit.sample_variance_f64(i, su)[c] * s2,
                    scaled.sample_variance_f64(i, ss)[c],
                    "variance",
                ),
            ];
            for (want, got, name) in pairs {
                assert!(
                    want.to_bits() == got.to_bits(),
                    "{what}: pixel {i} channel {c} {name}: {got:e}, want {want:e}"
                );
            }
            lit += (unit.sum[i][c] > 0.0) as usize;
        }
        assert_eq!(unit.weight[i].to_bits(), scaled.weight[i].to_bits());
        assert_eq!(unit.weight_sq[i].to_bits(), scaled.weight_sq[i].to_bits());
        assert_eq!(
            unit.weight_cube[i].to_bits(),
            scaled.weight_cube[i].to_bits()
        );
    }
    assert!(
        lit > unit.sum.len() * 2,
        "{what}: most pixel-channels are lit ({lit})"
    );
    // The f32 image too (normal in f32 at both factors).
    for (a, b) in unit.image().iter().zip(scaled.image()) {
        for c in 0..3 {
            assert_eq!((a[c] * s as f32).to_bits(), b[c].to_bits(), "{what}: image");
        }
    }
}

/// Issue 40's test: the Cornell box with its emitter scaled by 2⁻⁶⁶ and 2⁵³, rendered
/// through `render_progressive` in three passes, gives the unit render's sums times the
/// factor bit for bit (variances times its square); with the literal factors 1e-20 and
/// 1e16, within a few f32 ulps per pixel.
#[test]
fn scaled_cornell_box_renders_the_unit_image_times_the_factor() {
    // 16² pixels: passes of 1024 spp; 2560 spp are three passes, the last one partial.
    let spp = 2560;
    let unit = progressive_film(&cornell_scaled(16, None), spp);
    for e in [-66, 53] {
        let s = 2f64.powi(e);
        let scaled = progressive_film(&cornell_scaled(16, Some(s)), spp);
        assert_scaled_bitwise(&unit, &scaled, s, &format!("2^{e}"));
        if e > 0 {
            // f32 variances: in range at 2^53 (2^106 times the unit's), bit for bit.
            for (a, b) in unit.sample_variance().iter().zip(scaled.sample_variance()) {
                for c in 0..3 {
                    assert_eq!((a[c] * (s * s) as f32).to_bits(), b[c].to_bits());
                }
            }
        }
    }
    let ulp = |x: f32| (f32::from_bits(x.to_bits() + 1) - x).abs();
    for (e, s) in [(-20, 1e-20f64), (16, 1e16)] {
        let scaled = progressive_film(&cornell_literal(16, e), spp);
        let (mut worst_ulps, mut worst_var) = (0.0f64, 0.0f64);
        let (su, ss) = (unit.spp(), scaled.spp());
        for (i, (a, b)) in unit.image().iter().zip(scaled.image()).enumerate() {
            for c in 0..3 {
                let want = (unit.mean_f64(i)[c] * s) as f32;
                let d = (b[c] - want).abs() as f64 / ulp(want) as f64;
                worst_ulps = worst_ulps.max(if want == 0.0 {
                    assert_eq!(b[c], 0.0);
                    assert_eq!(a[c], 0.0);
                    0.0
                } else {
                    d
                });
                let m = unit.mean_f64(i)[c];
                let (vu, vs) = (
                    unit.sample_variance_f64(i, su)[c],
                    scaled.sample_variance_f64(i, ss)[c] / (s * s),
                );
                if vu + m * m > 0.0 {
                    worst_var = worst_var.max((vs - vu).abs() / (vu + m * m));
                }
            }
        }
        eprintln!("1e{e}: worst image difference {worst_ulps} f32 ulps, variance {worst_var:e}");
        assert!(worst_ulps <= 4.0, "1e{e}: {worst_ulps} ulps");
        assert!(
            worst_var < 1e-6,
            "1e{e}: variance off by {worst_var:e} of the second moment"
        );
    }
}

/// `target_rel_error` stops at the same pass for the scene scaled by 2⁻⁶⁶ and 2⁵³ as for the
/// unit scene: its error estimate is computed in f64 and scales exactly.
#[test]
fn target_error_stops_at_the_same_pass_at_any_power_of_two_scale() {
    // 8² pixels: passes of 256 spp. The target is the unit render's error after its fourth
    // pass, so the unit render stops there.
    let errors_of = |scene: &Job, target: Option<f64>, kind| {
        let errors = std::sync::Mutex::new(Vec::new());
        let s = ProgressiveSettings {
            target_rel_error: target.map(|t| (t, kind)),
            ..settings(256 * 12)
        };
        let (p, reason) = render_progressive(scene, &s, None, &|p| {
            errors
                .lock()
                .unwrap()
                .push(relative_standard_error(&p.film, kind))
        })
        .expect("renders");
        (p.samples, reason, errors.into_inner().unwrap())
    };
    for kind in [ErrorTarget::ImageMean, ErrorTarget::PerPixel] {
        let unit_scene = cornell_scaled(8, None);
        let (_, _, errors) = errors_of(&unit_scene, None, kind);
        let target = errors[3];
        assert!(
            errors[..3].iter().all(|e| *e > target),
            "{kind:?}: {errors:?}"
        );
        let (spp, reason, _) = errors_of(&unit_scene, Some(target), kind);
        assert_eq!(
            (spp, reason),
            (4 * 256, StopReason::TargetError),
            "{kind:?}: unit"
        );
        for e in [-66, 53] {
            let scene = cornell_scaled(8, Some(2f64.powi(e)));
            let (spp, reason, errs) = errors_of(&scene, Some(target), kind);
            assert_eq!(
                (spp, reason),
                (4 * 256, StopReason::TargetError),
                "{kind:?}: 2^{e} stops elsewhere (errors {errs:?}, unit {errors:?})"
            );
            assert_eq!(errs[..], errors[..4], "{kind:?}: 2^{e}: errors differ");
        }
    }
}

/// The same render in one process, in 3 and in 5 parts merged in scrambled orders, and
/// resumed from a checkpoint half-way: identical exact state bytes.
#[test]
fn any_grouping_of_a_render_gives_the_same_state_bytes() {
    let scene = cornell_scaled(16, None);
    let spp = 5 * 1024;
    let (whole, _) = render_progressive(&scene, &settings(spp), None, &|_| {}).expect("renders");
    let bytes = whole.exact.state_bytes();
    for n in [3u32, 5] {
        let mut parts: Vec<(PathBuf, Checkpoint)> = (0..n)
            .map(|i| {
                let plan = PartPlan {
                    index: i,
                    count: n,
                    plan_spp: spp as u64,
                    start_spp: 0,
                };
                let c = render_part(&scene, &plan, SEED, None, 0).expect("part");
                (PathBuf::from(format!("part-{i}")), c)
            })
            .collect();
        parts.reverse();
        parts.swap(0, 1);
        let merged = merge_parts(parts, None).expect("merges");
        assert!(
            merged.exact.state_bytes() == bytes,
            "{n} parts: other state bytes"
        );
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("exact-film-grouping");
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let ckpt = dir.join("half.ckpt");
    let with_ckpt = |spp| ProgressiveSettings {
        checkpoint: Some(penumbra::progressive::Checkpointing {
            path: ckpt.clone(),
            every: std::time::Duration::from_secs(3600),
        }),
        ..settings(spp)
    };
    render_progressive(&scene, &with_ckpt(2 * 1024), None, &|_| {}).expect("first half");
    let c = Checkpoint::read(&ckpt).expect("checkpoint");
    let (resumed, _) =
        render_progressive(&scene, &with_ckpt(spp), Some(c), &|_| {}).expect("resumes");
    assert!(
        resumed.exact.state_bytes() == bytes,
        "resumed: other state bytes"
    );
    // And the final checkpoint file's film section is those bytes.
    let file = std::fs::read(&ckpt).expect("checkpoint bytes");
    assert!(
        file.windows(bytes.len()).any(|w| w == bytes),
        "the checkpoint holds the canonical state"
    );
}

/// Merging 64 part files streams: the result is bit-identical to the one-process render, and
/// the memory the merge holds (peak live bytes on its thread) is about three films (the
/// merged one, a file's bytes, the part read from them) plus each part's header, where
/// holding every part would take 64 films.
#[test]
fn merging_64_part_files_streams_in_bounded_memory() {
    let scene = cornell_scaled(8, None);
    let pass = 256u64; // 8² pixels
    let n = 64u32;
    let spp = n as u64 * pass;
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("exact-film-64-parts");
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let mut paths: Vec<PathBuf> = (0..n)
        .map(|i| {
            let plan = PartPlan {
                index: i,
                count: n,
                plan_spp: spp,
                start_spp: 0,
            };
            let c = render_part(&scene, &plan, SEED, None, 0).expect("part");
            let p = dir.join(format!("p{i}.pnbr"));
            c.write(&p).expect("writes");
            p
        })
        .collect();
    let in_order = paths.clone();
    Rng(64).shuffle(&mut paths);
    let film_bytes = {
        let (whole, _) =
            render_progressive(&scene, &settings(spp as u32), None, &|_| {}).expect("renders");
        let merged = merge_part_files(&paths, None).expect("merges");
        assert!(
            merged.exact.state_bytes() == whole.exact.state_bytes(),
            "64 parts: other state bytes than the one-process render"
        );
        assert!(
            merged.film().image() == whole.film.image(),
            "64 parts: another image"
        );
        whole.exact.state_bytes().len() as i64
    };
    let (_, peak_8) =
        peak_bytes_of(|| merge_part_files(&in_order[..8], Some(8 * pass)).expect("merges"));
    let (merged, peak_64) = peak_bytes_of(|| merge_part_files(&paths, None));
    merged.expect("merges");
    eprintln!(
        "merge peak: {peak_8} B for 8 parts, {peak_64} B for 64; one film's state is {film_bytes} B"
    );
    // Three films at once (the merged one, a file's bytes, the part read from them) and a
    // header with its path per part, allowed 1 KiB each as below. The headers' share depends
    // on the length of the temporary directory's path (a bound of five films alone passed
    // here with 134 B to spare and failed in CI's longer checkout path).
    let bound = 4 * film_bytes + i64::from(n) * 1024;
    assert!(
        peak_64 < bound,
        "64 parts held {peak_64} B at once: more than a few films of {film_bytes} B and their headers ({bound} B)"
    );
    // Per part beyond the eighth, only its header and path stay (a few hundred bytes), not
    // its film.
    let per_part = (peak_64 - peak_8) / 56;
    assert!(
        per_part < 1024,
        "the merge's memory grows by {per_part} B per part ({peak_8} B for 8, {peak_64} B for 64)"
    );
}

// ---------------------------------------------------------------------------------------
// The previous format (PNBRCKP4).

fn v4_path(name: &str) -> PathBuf {
    repo_path(&format!("tests/data/exact-film/{name}"))
}

/// The i128 counts of a PNBRCKP4 file, read from its bytes here (the layout of d317463).
fn v4_counts(bytes: &[u8]) -> (usize, Vec<i128>) {
    assert_eq!(&bytes[..8], b"PNBRCKP4");
    let vlen = u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize;
    let at = 12 + vlen;
    let u64_at =
        |k: usize| u64::from_le_bytes(bytes[at + 8 * k..at + 8 * k + 8].try_into().unwrap());
    let (w, h) = (u64_at(6) as usize, u64_at(7) as usize);
    let film = at + 9 * 8 + 5 * 4 + 8 + 5 * 8 + 8;
    let counts = bytes[film..film + w * h * EXACT_VALUES * 16]
        .chunks_exact(16)
        .map(|c| i128::from_le_bytes(c.try_into().unwrap()))
        .collect();
    (w * h, counts)
}

/// A checkpoint of the previous format reads, each count q becoming exactly q · 2⁻⁴⁸; its
/// image equals the one the old code wrote; and the render resumes from it.
#[test]
fn old_checkpoints_convert_exactly_and_resume() {
    let path = v4_path("v4-cornell-res8-seed5-512spp.ckpt");
    let bytes = std::fs::read(&path).expect("test data");
    let (pixels, counts) = v4_counts(&bytes);
    let c = Checkpoint::read(&path).expect("an old checkpoint reads");
    assert_eq!((c.exact.width, c.exact.height, c.samples), (8, 8, 512));
    let film = c.film();
    let mut nonzero = 0;
    for p in 0..pixels {
        for k in 0..EXACT_VALUES {
            let q = counts[p * EXACT_VALUES + k];
            // Exact: the value times 2^48 is the integer q.
            let (neg, mag, exp) = c.exact.value(p, k).to_magnitude();
            let mut v: i128 = 0;
            for (i, l) in mag.iter().enumerate() {
                for b in 0..64 {
                    if l >> b & 1 == 1 {
                        let shift = exp + 48 + 64 * i as i64 + b as i64;
                        assert!((0..127).contains(&shift), "a bit below 2^-48");
                        v += 1i128 << shift;
                    }
                }
            }
            assert_eq!(if neg { -v } else { v }, q, "pixel {p} value {k}");
            nonzero += (q != 0) as usize;
            // The read-out is the old code's q / 2^48.
            let old = q as f64 / 281474976710656.0;
            let new = match k {
                0..=2 => film.sum[p][k],
                3..=5 => film.sum_sq[p][k - 3],
                6..=8 => film.sum_w2[p][k - 6],
                9..=11 => film.sum_sq_w2[p][k - 9],
                12 => film.weight[p],
                13 => film.weight_sq[p],
                _ => film.weight_cube[p],
            };
            assert_eq!(old.to_bits(), new.to_bits(), "pixel {p} value {k}");
        }
    }
    assert!(nonzero > pixels * 10);
    let old_image =
        penumbra::io::exr::read(&v4_path("v4-cornell-res8-seed5-512spp.exr")).expect("old image");
    assert!(
        old_image.rgb == film.image(),
        "the old code's image of the same sums"
    );
    // Resume to 1024 spp: the old sums plus the two further passes, exactly.
    let mut scene = cornell_scaled(8, None);
    scene.scene.sampler.sample_count = c.sampler_points;
    let s = ProgressiveSettings {
        seed: 5,
        scene_hash: c.scene_hash,
        ..settings(1024)
    };
    let mut want = c.exact.clone();
    for first_sample in [512, 768] {
        let out = scene
            .render(
                &RenderSettings {
                    spp: 256,
                    seed: 5,
                    threads: None,
                    sampler: None,
                    first_sample,
                },
                &|_, _| {},
            )
            .expect("pass");
        want.add(&out.film).expect("adds");
    }
    let (p, reason) = render_progressive(&scene, &s, Some(c), &|_| {}).expect("resumes");
    assert_eq!((p.samples, reason), (1024, StopReason::SppReached));
    assert!(p.exact == want, "the resumed sums");
}

/// A part file of the previous format merges with a part of today's.
#[test]
fn old_part_files_merge_with_new_ones() {
    let old = Checkpoint::read(&v4_path("v4-cornell-res8-seed5-part0of2-1024spp.pnbr"))
        .expect("an old part reads");
    assert_eq!(
        (old.part, old.first_sample, old.samples),
        (Some((0, 2)), 0, 512)
    );
    let mut scene = cornell_scaled(8, None);
    scene.scene.sampler.sample_count = old.sampler_points;
    let plan = PartPlan {
        index: 1,
        count: 2,
        plan_spp: 1024,
        start_spp: 0,
    };
    let new = render_part(&scene, &plan, 5, None, old.scene_hash).expect("part");
    let mut want = old.exact.clone();
    want.add_exact(&new.exact).expect("adds");
    let merged = merge_parts(
        vec![(PathBuf::from("new"), new), (PathBuf::from("old"), old)],
        None,
    )
    .expect("merges");
    assert_eq!(merged.samples, 1024);
    assert!(merged.exact == want);
}

/// Hostile checkpoint files: a resolution the file does not hold, a huge spill count, a
/// truncated file. Each is one clear error (the checksum recomputed so that the checks behind
/// it are reached), never a panic or a huge allocation.
#[test]
fn hostile_checkpoint_files_are_one_clear_error() {
    let scene = cornell_scaled(8, None);
    let plan = PartPlan {
        index: 0,
        count: 1,
        plan_spp: 256,
        start_spp: 0,
    };
    let c = render_part(&scene, &plan, SEED, None, 0).expect("part");
    let good = c.to_bytes();
    let fnv = |b: &[u8]| {
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        for x in b {
            h ^= *x as u64;
            h = h.wrapping_mul(0x100_0000_01b3);
        }
        h
    };
    let resealed = |mut b: Vec<u8>| {
        let n = b.len() - 8;
        let h = fnv(&b[..n]);
        b[n..].copy_from_slice(&h.to_le_bytes());
        b
    };
    let parse = |b: &[u8]| Checkpoint::parse(b, Path::new("hostile.pnbr"));
    assert!(parse(&good).is_ok());
    let vlen = u32::from_le_bytes(good[8..12].try_into().unwrap()) as usize;
    let at = 12 + vlen;
    let mut cases: Vec<(Vec<u8>, &str)> = Vec::new();
    // 8192 × 8192 pixels (the limit) in a file of 17 KB.
    let mut b = good.clone();
    b[at + 48..at + 56].copy_from_slice(&8192u64.to_le_bytes());
    b[at + 56..at + 64].copy_from_slice(&8192u64.to_le_bytes());
    cases.push((resealed(b), "shorter than its resolution"));
    // Beyond the pixel limit.
    let mut b = good.clone();
    b[at + 48..at + 56].copy_from_slice(&u64::MAX.to_le_bytes());
    cases.push((resealed(b), "resolution"));
    // A huge spill count.
    let film = at + 9 * 8 + 5 * 4 + 8 + 5 * 8 + 8;
    let count_at = film + 1 + 64 * EXACT_VALUES * 18;
    let mut b = good.clone();
    b[count_at..count_at + 8].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
    cases.push((resealed(b), "spill count"));
    // Truncated (resealed), and a version string longer than any.
    cases.push((
        resealed(good[..good.len() - 100].to_vec()),
        "shorter than its resolution",
    ));
    let mut b = good.clone();
    b[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    cases.push((resealed(b), "bad version"));
    for (b, why) in cases {
        let e = parse(&b).map(|_| ()).expect_err("refused").to_string();
        assert!(e.contains(why) && !e.contains('\n'), "{why}: {e}");
        assert!(e.contains("not a valid penumbra checkpoint"), "{e}");
    }
    // The header alone: a merge plans from it and checks the file's length.
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("exact-film-hostile");
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let p = dir.join("short.pnbr");
    std::fs::write(&p, &good[..good.len() / 2]).expect("writes");
    let e = merge_part_files(&[p], None)
        .map(|_| ())
        .expect_err("refused");
    assert!(e.to_string().contains("size does not match"), "{e}");
}
