//! The exact film's accumulator (issue 40): nanoseconds per added value for three
//! distributions of terms, on one thread:
//!
//! - `unit`: sums as a unit-scale render's passes make them (f64 values in [0.5, 4)),
//! - `40-binades`: terms log-uniform over 40 binades around 1, random signs,
//! - `firefly`: unit terms, and in one pixel in 64 a term of 1e60 (a 1e30 firefly's square),
//!   which sends that pixel's sums to the spill path;
//!
//! for one [`ExactSum`] (the scalar accumulator) and for a 64 × 64 [`ExactFilm`] (a pass
//! film's 15 sums per pixel added, in chunks of 1024 pixels); a merge of two exact films
//! (`add_exact`, per pixel) and the read-out to an f64 film (`to_film`, per pixel).
//! Run with `cargo bench --bench exact_film`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use penumbra::film::{ExactFilm, ExactSum, Film, Filter, EXACT_VALUES};
use std::hint::black_box;
use std::time::Duration;

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn double(&mut self, exps: std::ops::Range<u64>, signed: bool) -> f64 {
        let exp = exps.start + self.next() % (exps.end - exps.start);
        let sign = if signed { self.next() & 1 } else { 0 };
        f64::from_bits(sign << 63 | exp << 52 | self.next() >> 12)
    }
}

const KINDS: [&str; 3] = ["unit", "40-binades", "firefly"];

fn term(rng: &mut Rng, kind: &str, i: usize) -> f64 {
    match kind {
        "unit" => rng.double(1022..1025, false),
        "40-binades" => rng.double(1003..1043, true),
        _ if i.is_multiple_of(64) => 1e60,
        _ => rng.double(1022..1025, false),
    }
}

fn film_of(rng: &mut Rng, kind: &str, w: usize, h: usize) -> Film {
    let mut f = Film::new(w, h, Filter::Box);
    for i in 0..w * h {
        let mut t = || term(rng, kind, i);
        f.sum[i] = [t(), t(), t()];
        f.sum_sq[i] = [t(), t(), t()];
        f.sum_w2[i] = [t(), t(), t()];
        f.sum_sq_w2[i] = [t(), t(), t()];
        f.weight[i] = t();
        f.weight_sq[i] = t();
        f.weight_cube[i] = t();
    }
    f.samples = (w * h) as u64;
    f
}

fn bench(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut g = c.benchmark_group("exact-sum-add");
    let n = 4096;
    for kind in KINDS {
        let mut rng = Rng(1);
        let terms: Vec<f64> = (0..n).map(|i| term(&mut rng, kind, i)).collect();
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::from_parameter(kind), &terms, |b, terms| {
            // 64 accumulators, each taking every 64th term: adds into a warm state.
            let mut sums = vec![ExactSum::new(); 64];
            b.iter(|| {
                for (i, &t) in terms.iter().enumerate() {
                    let _ = sums[i % 64].add_f64(black_box(t));
                }
            })
        });
    }
    g.finish();

    let (w, h) = (64, 64);
    let mut g = c.benchmark_group("exact-film-add");
    for kind in KINDS {
        let mut rng = Rng(2);
        let passes: Vec<Film> = (0..4).map(|_| film_of(&mut rng, kind, w, h)).collect();
        let mut exact = ExactFilm::new(w, h);
        g.throughput(Throughput::Elements((w * h * EXACT_VALUES) as u64));
        g.bench_function(BenchmarkId::from_parameter(kind), |b| {
            let mut k = 0;
            b.iter(|| {
                k = (k + 1) % passes.len();
                pool.install(|| exact.add(&passes[k])).expect("adds");
            })
        });
    }
    g.finish();

    let mut g = c.benchmark_group("exact-film-per-pixel");
    g.throughput(Throughput::Elements((w * h) as u64));
    for kind in KINDS {
        let mut rng = Rng(3);
        let mut a = ExactFilm::new(w, h);
        let mut other = ExactFilm::new(w, h);
        for _ in 0..8 {
            a.add(&film_of(&mut rng, kind, w, h)).expect("adds");
            other.add(&film_of(&mut rng, kind, w, h)).expect("adds");
        }
        g.bench_function(BenchmarkId::new("merge", kind), |b| {
            b.iter(|| {
                pool.install(|| a.add_exact(black_box(&other)))
                    .expect("merges")
            })
        });
        g.bench_function(BenchmarkId::new("read-out", kind), |b| {
            b.iter(|| pool.install(|| black_box(a.to_film(Filter::Box))))
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = bench
}
criterion_main!(benches);
