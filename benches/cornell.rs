//! Paths per second on the Cornell box (scenes/cornell-box.xml at 64x64, 4 spp per
//! iteration). Run with `cargo bench --bench cornell`; criterion reports the throughput in
//! elements (camera paths) per second.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use penumbra::render::Job;
use penumbra::render::RenderSettings;
use std::path::Path;

fn cornell(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.xml");
    let scene = Job::load(&path, &[("res".into(), "64".into())]).expect("scene loads");
    let spp = 4;
    let settings = RenderSettings {
        spp,
        seed: 0,
        threads: None,
        sampler: None,
        first_sample: 0,
    };
    let mut group = c.benchmark_group("cornell-box");
    group.throughput(Throughput::Elements(
        (scene.scene.width * scene.scene.height) as u64 * spp as u64,
    ));
    group.sample_size(20);
    group.bench_function("render 64x64 4spp", |b| {
        b.iter(|| scene.render(&settings, &|_, _| {}).expect("render"))
    });
    group.finish();
}

criterion_group!(benches, cornell);
criterion_main!(benches);
