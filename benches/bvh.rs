//! BVH build time against triangle count (the Stanford bunny and procedurally subdivided
//! spheres), and closest-hit / occlusion rays per second on the bunny, coherent (a pinhole
//! camera's primary rays) and incoherent (random directions from random points in its bounds).
//! Run with `cargo bench --bench bvh`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{DMat4, Vec3};
use penumbra::accel::Accel;
use penumbra::geometry::Ray;
use penumbra::sampler::SampleStream;
use penumbra::scene::build::load_obj;
use penumbra::shape::{Mesh, Shape, ShapeGeometry};
use std::path::Path;

fn bunny() -> Vec<Shape> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/stanford-bunny.obj");
    let mesh =
        load_obj(&path, DMat4::IDENTITY, false, true, false, &mut Vec::new()).expect("bunny");
    vec![Shape {
        geometry: ShapeGeometry::Mesh(mesh),
        bsdf: 0,
        emitter: None,
    }]
}

/// A UV sphere with about `n` triangles.
pub fn sphere_mesh(n: usize) -> Vec<Shape> {
    let rings = ((n as f64 / 2.0).sqrt() as usize).max(3);
    let segs = rings;
    let mut p = Vec::new();
    for i in 0..=rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segs {
            let ph = 2.0 * std::f32::consts::PI * j as f32 / segs as f32;
            p.push(Vec3::new(
                th.sin() * ph.cos(),
                th.sin() * ph.sin(),
                th.cos(),
            ));
        }
    }
    let mut t = Vec::new();
    for i in 0..rings {
        for j in 0..segs {
            let a = (i * segs + j) as u32;
            let b = (i * segs + (j + 1) % segs) as u32;
            let c = a + segs as u32;
            let d = b + segs as u32;
            t.push([a, c, b]);
            t.push([b, c, d]);
        }
    }
    let mesh = Mesh::new(p, None, None, t, false);
    vec![Shape {
        geometry: ShapeGeometry::Mesh(mesh),
        bsdf: 0,
        emitter: None,
    }]
}

fn triangle_count(shapes: &[Shape]) -> usize {
    shapes
        .iter()
        .map(|s| match &s.geometry {
            ShapeGeometry::Mesh(m) => m.triangles.len(),
            _ => 1,
        })
        .sum()
}

fn build(c: &mut Criterion) {
    let mut g = c.benchmark_group("bvh-build");
    g.sample_size(10);
    let mut cases: Vec<(String, Vec<Shape>)> = vec![("bunny".into(), bunny())];
    for n in [1_000, 10_000, 100_000, 1_000_000] {
        cases.push((format!("sphere-{n}"), sphere_mesh(n)));
    }
    for (name, shapes) in &cases {
        let tris = triangle_count(shapes);
        g.throughput(Throughput::Elements(tris as u64));
        g.bench_with_input(
            BenchmarkId::new("build", format!("{name} ({tris} tris)")),
            shapes,
            |b, s| b.iter(|| Accel::build(s)),
        );
    }
    g.finish();
}

fn rays(c: &mut Criterion) {
    let shapes = bunny();
    let accel = Accel::build(&shapes);
    let n = 1 << 16;
    // Bunny bounds ~ [-0.1, 0.06] x [0.03, 0.19] x [-0.06, 0.06].
    let centre = Vec3::new(-0.017, 0.11, 0.0);
    let coherent: Vec<Ray> = (0..n)
        .map(|i| {
            let (x, y) = (
                (i % 256) as f32 / 256.0 - 0.5,
                (i / 256) as f32 / 256.0 - 0.5,
            );
            let o = centre + Vec3::new(0.0, 0.0, 0.4);
            Ray::new(
                o,
                Vec3::new(x * 0.5, -y * 0.5, -1.0).normalize(),
                f32::INFINITY,
            )
        })
        .collect();
    let incoherent: Vec<Ray> = (0..n)
        .map(|i| {
            let mut s = SampleStream::new(1, i as u64, 0);
            let o = centre + (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 0.2;
            let d = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5).normalize();
            Ray::new(o, d, f32::INFINITY)
        })
        .collect();
    let mut g = c.benchmark_group("bunny-rays");
    g.throughput(Throughput::Elements(n as u64));
    g.sample_size(20);
    for (name, rays) in [("coherent", &coherent), ("incoherent", &incoherent)] {
        g.bench_function(format!("closest-hit {name}"), |b| {
            b.iter(|| {
                rays.iter()
                    .filter(|r| accel.intersect(r, &shapes).is_some())
                    .count()
            })
        });
        g.bench_function(format!("occlusion {name}"), |b| {
            b.iter(|| rays.iter().filter(|r| accel.occluded(r, &shapes)).count())
        });
    }
    g.finish();
}

criterion_group!(benches, build, rays);
criterion_main!(benches);
