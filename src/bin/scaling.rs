//! Scaling study (issue 8): how time grows with triangle count (BVH build and rays/s on
//! spheres of 1k to 10M triangles, each size in a fresh process so that its peak memory can be
//! read), with pixels × spp, and with threads. Prints markdown tables.
//!
//!     cargo run --release --bin scaling [-- tris|pixels|threads] [--max-tris N]

use glam::Vec3;
use penumbra::accel::Accel;
use penumbra::geometry::Ray;
use penumbra::render::{Job, RenderSettings};
use penumbra::shape::{Mesh, Shape, ShapeGeometry};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// A UV sphere of radius 1 with about `n` triangles.
fn sphere(n: usize) -> Vec<Shape> {
    let rings = ((n as f64 / 2.0).sqrt() as usize).max(3);
    let mut p = Vec::with_capacity((rings + 1) * rings);
    for i in 0..=rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..rings {
            let ph = 2.0 * std::f32::consts::PI * j as f32 / rings as f32;
            p.push(Vec3::new(
                th.sin() * ph.cos(),
                th.sin() * ph.sin(),
                th.cos(),
            ));
        }
    }
    let mut t = Vec::with_capacity(2 * rings * rings);
    for i in 0..rings {
        for j in 0..rings {
            let a = (i * rings + j) as u32;
            let b = (i * rings + (j + 1) % rings) as u32;
            let (c, d) = (a + rings as u32, b + rings as u32);
            t.push([a, c, b]);
            t.push([b, c, d]);
        }
    }
    vec![Shape {
        geometry: ShapeGeometry::Mesh(Mesh::new(p, None, None, t, false)),
        material: 0,
        emitter: None,
        interior: None,
        exterior: None,
    }]
}

/// Peak resident memory of this process, in MiB (Linux: VmHWM).
fn peak_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| {
                l.split_whitespace()
                    .nth(1)
                    .and_then(|k| k.parse::<f64>().ok())
            })
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

/// One size, in this process: prints "tris build_s rays_per_s peak_after_build_mib base_mib"
/// (peak resident memory once the mesh and BVH exist, and before anything was built).
fn one_tri(n: usize) {
    let base = peak_mib();
    let shapes = sphere(n);
    let tris = match &shapes[0].geometry {
        ShapeGeometry::Mesh(m) => m.triangles.len(),
        _ => 0,
    };
    let t0 = Instant::now();
    let accel = Accel::build(&shapes);
    let build = t0.elapsed().as_secs_f64();
    let built = peak_mib();
    // 2^18 rays from a ring around the sphere towards random points near its centre.
    let rays: Vec<Ray> = (0..1u64 << 18)
        .map(|i| {
            let mut s = penumbra::sampler::SampleStream::new(7, i, 0);
            let a = s.next_1d() * std::f32::consts::TAU;
            let o = Vec3::new(3.0 * a.cos(), 3.0 * a.sin(), s.next_1d() - 0.5);
            let target = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 1.2;
            Ray::new(o, (target - o).normalize(), f32::INFINITY)
        })
        .collect();
    let t0 = Instant::now();
    let hits = rays
        .iter()
        .filter(|r| accel.intersect(r, &shapes).is_some())
        .count();
    let secs = t0.elapsed().as_secs_f64();
    assert!(hits > 0);
    println!("{tris} {build} {} {built} {base}", rays.len() as f64 / secs);
}

fn tris(max: usize) {
    println!("| triangles | BVH build (s) | closest-hit rays/s (1 thread) | peak memory after build (MiB) | MiB per 1M triangles (mesh + BVH) |");
    println!("|---:|---:|---:|---:|---:|");
    let exe = std::env::current_exe().expect("own path");
    let mut n = 1_000;
    while n <= max {
        let out = Command::new(&exe)
            .args(["one-tri", &n.to_string()])
            .output()
            .expect("child");
        let text = String::from_utf8_lossy(&out.stdout);
        let v: Vec<f64> = text
            .split_whitespace()
            .filter_map(|x| x.parse().ok())
            .collect();
        if v.len() == 5 {
            let per_m = (v[3] - v[4]) / (v[0] / 1e6);
            println!(
                "| {:.0} | {:.3} | {:.3e} | {:.0} | {:.0} |",
                v[0], v[1], v[2], v[3], per_m
            );
        } else {
            println!(
                "| {n} | failed: {} | | | |",
                String::from_utf8_lossy(&out.stderr)
                    .lines()
                    .last()
                    .unwrap_or("")
            );
        }
        n *= 10;
    }
}

fn cornell(res: u32) -> Job {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.xml");
    Job::load(&path, &[("res".into(), res.to_string())]).expect("cornell box")
}

fn time_render(job: &Job, spp: u32, threads: Option<usize>) -> f64 {
    let s = RenderSettings {
        spp,
        seed: 1,
        threads,
        sampler: None,
        first_sample: 0,
    };
    job.render(&s, &|_, _| {}).expect("render").stats.seconds
}

fn pixels() {
    println!("| pixels x spp | resolution | spp | seconds | ns per path |");
    println!("|---:|---|---:|---:|---:|");
    for (res, spp) in [
        (32, 16),
        (64, 16),
        (128, 16),
        (64, 64),
        (128, 64),
        (256, 16),
    ] {
        let scene = cornell(res);
        let secs = time_render(&scene, spp, None);
        let paths = (res * res * spp) as f64;
        println!(
            "| {paths} | {res}x{res} | {spp} | {secs:.3} | {:.0} |",
            secs / paths * 1e9
        );
    }
}

fn threads() {
    let scene = cornell(128);
    println!("| threads | seconds (Cornell box 128x128, 32 spp; median of 3) | speed-up |");
    println!("|---:|---:|---:|");
    let median = |t: usize| {
        let mut v: Vec<f64> = (0..3).map(|_| time_render(&scene, 32, Some(t))).collect();
        v.sort_by(f64::total_cmp);
        v[1]
    };
    let one = median(1);
    println!("| 1 | {one:.3} | 1.00 |");
    let two = median(2);
    println!("| 2 | {two:.3} | {:.2} |", one / two);
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let max = args
        .iter()
        .position(|a| a == "--max-tris")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000_000);
    match args.first().map(String::as_str) {
        Some("one-tri") => one_tri(args.get(1).and_then(|v| v.parse().ok()).unwrap_or(1000)),
        Some("tris") => tris(max),
        Some("pixels") => pixels(),
        Some("threads") => threads(),
        _ => {
            tris(max);
            println!();
            pixels();
            println!();
            threads();
        }
    }
}
