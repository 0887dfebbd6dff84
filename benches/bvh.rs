//! BVH build time against triangle count (the Stanford bunny and procedurally subdivided
//! spheres), and closest-hit / occlusion rays per second on the bunny, coherent (a pinhole
//! camera's primary rays) and incoherent (random directions from random points in its bounds).
//! The `bvh-layouts` group traces the same rays through obvhs's binary BVH (`Bvh2`) and its
//! 8-wide compressed BVH (`CwBvh`, Ylitie et al. 2017), both built by obvhs's
//! `medium_build` and calling penumbra's scalar watertight triangle test, and through
//! penumbra's own 4-wide and 8-wide (AVX2) BVHs (`Accel`): which layout traverses fastest
//! here.
//! Run with `cargo bench --bench bvh`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{DMat4, Vec3};
use obvhs::aabb::Aabb;
use obvhs::ray::RayHit;
use obvhs::{Boundable, BvhBuildParams};
use penumbra::accel::{Accel, Layout};
use penumbra::geometry::Ray;
use penumbra::sampler::SampleStream;
use penumbra::scene::build::load_obj;
use penumbra::shape::mesh::{intersect_triangle, RayShear};
use penumbra::shape::{Mesh, Shape, ShapeGeometry};
use std::path::Path;
use std::time::Duration;

fn bunny() -> Vec<Shape> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/stanford-bunny.obj");
    let mesh =
        load_obj(&path, DMat4::IDENTITY, false, true, false, &mut Vec::new()).expect("bunny");
    vec![Shape {
        geometry: ShapeGeometry::Mesh(mesh),
        material: 0,
        emitter: None,
        interior: None,
        exterior: None,
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
        material: 0,
        emitter: None,
        interior: None,
        exterior: None,
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
    let [(_, coherent), (_, incoherent)] = bunny_rays(n);
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

/// The bunny's coherent and incoherent rays of [`rays`].
fn bunny_rays(n: usize) -> [(&'static str, Vec<Ray>); 2] {
    // Bunny bounds ~ [-0.1, 0.06] x [0.03, 0.19] x [-0.06, 0.06].
    let centre = Vec3::new(-0.017, 0.11, 0.0);
    let coherent = (0..n)
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
    let incoherent = (0..n)
        .map(|i| {
            let mut s = SampleStream::new(1, i as u64, 0);
            let o = centre + (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 0.2;
            let d = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5).normalize();
            Ray::new(o, d, f32::INFINITY)
        })
        .collect();
    [("coherent", coherent), ("incoherent", incoherent)]
}

struct Tri([Vec3; 3]);

impl Boundable for Tri {
    fn aabb(&self) -> Aabb {
        let mut a = Aabb::empty();
        for p in self.0 {
            a.extend(p.into());
        }
        a
    }
}

fn layouts(c: &mut Criterion) {
    let shapes = bunny();
    let ShapeGeometry::Mesh(mesh) = &shapes[0].geometry else {
        unreachable!()
    };
    let tris: Vec<Tri> = (0..mesh.triangles.len())
        .map(|i| Tri(mesh.vertices(i)))
        .collect();
    let bvh2 = obvhs::bvh2::builder::build_bvh2(
        &tris,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let cwbvh = obvhs::cwbvh::builder::build_cwbvh(
        &tris,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let accel = Accel::build_with_layout(&shapes, Layout::Wide4);
    let accel8 = Accel::build_with_layout(&shapes, Layout::Wide8);
    // penumbra's triangle test on the triangle in BVH slot `slot`.
    let test = |order: &[u32], shear: &RayShear, r: &obvhs::ray::Ray, slot: usize| {
        intersect_triangle(shear, &tris[order[slot] as usize].0, r.tmax)
            .map_or(f32::INFINITY, |h| h.0)
    };
    let to_obvhs = |r: &Ray| obvhs::ray::Ray::new_inf(r.o.into(), r.d.into());
    // Closest-hit distance (∞ for a miss) and occlusion through each layout.
    let bvh2_closest = |r: &Ray| {
        let shear = RayShear::new(r.o, r.d);
        let mut hit = RayHit::none();
        bvh2.ray_traverse(to_obvhs(r), &mut hit, |ray, slot| {
            test(&bvh2.primitive_indices, &shear, ray, slot)
        });
        hit.t
    };
    let cwbvh_closest = |r: &Ray| {
        let shear = RayShear::new(r.o, r.d);
        let mut hit = RayHit::none();
        cwbvh.ray_traverse(to_obvhs(r), &mut hit, |ray, slot| {
            test(&cwbvh.primitive_indices, &shear, ray, slot)
        });
        hit.t
    };
    let accel_closest = |r: &Ray| accel.intersect(r, &shapes).map_or(f32::INFINITY, |h| h.t);
    let bvh2_occluded = |r: &Ray| {
        let shear = RayShear::new(r.o, r.d);
        !bvh2.ray_traverse_miss(to_obvhs(r), |ray, slot| {
            test(&bvh2.primitive_indices, &shear, ray, slot)
        })
    };
    let cwbvh_occluded = |r: &Ray| {
        let shear = RayShear::new(r.o, r.d);
        !cwbvh.ray_traverse_miss(to_obvhs(r), |ray, slot| {
            test(&cwbvh.primitive_indices, &shear, ray, slot)
        })
    };
    let accel_occluded = |r: &Ray| accel.occluded(r, &shapes);
    let accel8_closest = |r: &Ray| accel8.intersect(r, &shapes).map_or(f32::INFINITY, |h| h.t);
    let accel8_occluded = |r: &Ray| accel8.occluded(r, &shapes);

    let mut g = c.benchmark_group("bvh-layouts");
    let n = 1 << 16;
    g.throughput(Throughput::Elements(n as u64));
    g.sample_size(20);
    for (name, rays) in bunny_rays(n) {
        // The three should find the same hits before their speeds mean anything: count the
        // rays where obvhs's layouts disagree with the 4-wide BVH (which is checked against
        // brute force in its unit test), split by the two known causes.
        let mut hits = [0usize; 3];
        let mut wrong = [[0usize; 3]; 2]; // [Bvh2, CwBvh] x [axis-parallel, t < 1e-4, other]
        for r in &rays {
            let t = [bvh2_closest(r), cwbvh_closest(r), accel_closest(r)];
            for k in 0..3 {
                hits[k] += (t[k] < f32::INFINITY) as usize;
            }
            for k in 0..2 {
                if t[k] != t[2] {
                    let cause = if r.d.to_array().contains(&0.0) {
                        0
                    } else if t[2] < 1e-4 {
                        1
                    } else {
                        2
                    };
                    wrong[k][cause] += 1;
                }
            }
        }
        let differ8 = rays
            .iter()
            .filter(|r| accel8_closest(r) != accel_closest(r))
            .count();
        eprintln!(
            "{name}: the {:?} BVH's closest hits differ from the 4-wide one's on {differ8} rays",
            accel8.layout()
        );
        eprintln!(
            "{name}: {hits:?} hits of {n} rays (Bvh2, CwBvh, 4-wide); rays whose closest hit \
             differs from the 4-wide BVH's [axis-parallel, t < 1e-4, other]: Bvh2 {:?}, \
             CwBvh {:?}",
            wrong[0], wrong[1]
        );
        let mut bench = |id: String, hit: &dyn Fn(&Ray) -> bool| {
            g.bench_function(id, |b| b.iter(|| rays.iter().filter(|r| hit(r)).count()));
        };
        bench(format!("obvhs Bvh2 closest-hit {name}"), &|r| {
            bvh2_closest(r) < f32::INFINITY
        });
        bench(format!("obvhs CwBvh closest-hit {name}"), &|r| {
            cwbvh_closest(r) < f32::INFINITY
        });
        bench(format!("penumbra 4-wide closest-hit {name}"), &|r| {
            accel_closest(r) < f32::INFINITY
        });
        bench(format!("penumbra 8-wide closest-hit {name}"), &|r| {
            accel8_closest(r) < f32::INFINITY
        });
        bench(format!("obvhs Bvh2 occlusion {name}"), &bvh2_occluded);
        bench(format!("obvhs CwBvh occlusion {name}"), &cwbvh_occluded);
        bench(format!("penumbra 4-wide occlusion {name}"), &accel_occluded);
        bench(
            format!("penumbra 8-wide occlusion {name}"),
            &accel8_occluded,
        );
    }
    g.finish();
}

criterion_group!(benches, build, rays, layouts);
criterion_main!(benches);
