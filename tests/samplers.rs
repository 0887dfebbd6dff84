//! The samplers at scene level: unbiased against Mitsuba's reference, their dimensions and
//! neighbouring pixels uncorrelated, and renders that stay exact when continued, resumed or
//! split across threads. (Point-set properties, strata, Latin hypercubes, orthogonal arrays
//! and (0,m,2)-nets, are unit tests in src/sampler/.)

mod common;
use common::*;
use penumbra::io::exr;
use penumbra::render::Job;
use penumbra::render::RenderSettings;
use penumbra::sampler::{Sampler, SamplerKind};
use penumbra::study::stats::{normal_critical_z, sidak};

const KINDS: [&str; 6] = [
    "independent",
    "stratified",
    "multijitter",
    "orthogonal",
    "ldsampler",
    "zsobol",
];

fn sampler(name: &str, n: u32) -> Sampler {
    Sampler::new(SamplerKind::from_name(name).unwrap(), n).0
}

/// Pearson's r of paired values, as a z-score: r √(n − 3) (Fisher's z for small r), standard
/// normal when the two are uncorrelated.
fn correlation_z(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    let r = sab / (saa * sbb).sqrt();
    r.atanh() * (n - 3.0).sqrt()
}

/// Over 256 x 256 pixels, one sample each (pixels are independent draws; samples of one
/// pixel are not, by design): (1) dimension d against dimension d + 1, (2) their offsets
/// within the 1/16 strata (equal offsets are what Mitsuba's ldsampler, one scramble for all
/// dimensions, produces), (3) a pixel against its right-hand neighbour at the same sample
/// index and dimension (pixel pairs (2k, y), (2k + 1, y)). Every correlation is zero for a
/// sampler whose dimensions and pixels are independent; Šidák over all tests, α = 0.01.
#[test]
fn dimensions_and_neighbouring_pixels_are_uncorrelated() {
    let (w, h, n, dims) = (256u32, 256u32, 16u32, 8usize);
    let tests = KINDS.len() * (3 * (dims - 1));
    let z_crit = normal_critical_z(sidak(0.01, tests));
    let mut failures = Vec::new();
    for name in KINDS {
        let s = sampler(name, n);
        let n = s.sample_count;
        let draw = |x: u32, y: u32, i: u32| {
            let mut st = s.stream(3, (x, y), (w, h), i as u64);
            let mut v = [0.0f64; 8];
            for x in v.iter_mut() {
                *x = st.next_1d() as f64;
            }
            v
        };
        let mut same = Vec::new();
        let mut pairs = Vec::new();
        for y in 0..h {
            for k in 0..w / 2 {
                let i = (k + y) % n;
                let (p, q) = (draw(2 * k, y, i), draw(2 * k + 1, y, i));
                same.push(p);
                same.push(q);
                pairs.push((p, q));
            }
        }
        for d in 0..dims - 1 {
            let col = |d: usize| same.iter().map(|v| v[d]).collect::<Vec<_>>();
            let offsets = |d: usize| {
                same.iter()
                    .map(|v| (v[d] * n as f64).fract())
                    .collect::<Vec<_>>()
            };
            let left: Vec<f64> = pairs.iter().map(|(p, _)| p[d]).collect();
            let right: Vec<f64> = pairs.iter().map(|(_, q)| q[d]).collect();
            for (what, z) in [
                ("dimensions", correlation_z(&col(d), &col(d + 1))),
                (
                    "stratum offsets",
                    correlation_z(&offsets(d), &offsets(d + 1)),
                ),
                ("neighbouring pixels", correlation_z(&left, &right)),
            ] {
                if z.abs() > z_crit {
                    failures.push(format!("{name}: {what} {d}/{}: z = {z:.2}", d + 1));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "|z| > {z_crit:.2}:\n{}",
        failures.join("\n")
    );
}

/// Unbiased against Mitsuba 3.9.1: the Cornell box's image mean with every sampler equals
/// the mean of Mitsuba's 16384-spp reference (independent sampler). With the box filter the
/// image mean is the image-plane integral at any resolution, so the render is 64 x 64 (the
/// reference 128 x 128): 64 passes of 16 points. The standard error comes from the
/// per-pixel sample variance, which overestimates a stratified sampler's error (the test is
/// conservative, never too strict); Šidák over samplers and channels, α = 0.01. A bias of
/// Mitsuba's ldsampler's size (0.45%) is ~7 standard errors here.
#[test]
fn every_sampler_is_unbiased_on_the_cornell_box() {
    let scene = load("scenes/cornell-box.xml", &[("res", "64")]);
    let reference = exr::read(&repo_path("validation/references/cornell-box.exr")).unwrap();
    let ref_spp = reference.spp().unwrap();
    let var = reference.variance.as_ref().expect("reference variance");
    let npx = reference.rgb.len() as f64;
    let z_crit = normal_critical_z(sidak(0.01, KINDS.len() * 3));
    let mut failures = Vec::new();
    for name in KINDS {
        let s = sampler(name, 16);
        let spp = 64 * s.sample_count;
        let out = scene
            .render(
                &RenderSettings {
                    spp,
                    first_sample: 0,
                    seed: 5,
                    threads: None,
                    sampler: Some(s),
                },
                &|_, _| {},
            )
            .unwrap();
        let (mean, se) = image_mean_and_se(&out, spp);
        for c in 0..3 {
            let ref_mean = reference.rgb.iter().map(|p| p[c] as f64).sum::<f64>() / npx;
            let ref_var = var.iter().map(|p| p[c] as f64 / ref_spp).sum::<f64>() / (npx * npx);
            let z = (mean[c] - ref_mean) / (se[c] * se[c] + ref_var).sqrt();
            eprintln!(
                "{name} channel {c}: {:.6} vs {:.6} ({:+.3}%), z = {z:.2}",
                mean[c],
                ref_mean,
                100.0 * (mean[c] / ref_mean - 1.0)
            );
            if z.abs() > z_crit {
                failures.push(format!("{name} channel {c}: z = {z:.2}"));
            }
        }
    }
    assert!(failures.is_empty(), "|z| > {z_crit:.2}: {failures:?}");
}

/// Same bits at one and two threads, and a render continued in pieces (as --resume and
/// ladders do) adds up to the uninterrupted one, pass boundaries included.
#[test]
fn stratified_renders_are_deterministic_and_continue_exactly() {
    let scene = load("scenes/cornell-box.xml", &[("res", "20")]);
    for name in KINDS {
        let s = sampler(name, 9);
        let run = |spp, first_sample, threads| {
            scene
                .render(
                    &RenderSettings {
                        spp,
                        first_sample,
                        seed: 11,
                        threads,
                        sampler: Some(s),
                    },
                    &|_, _| {},
                )
                .unwrap()
                .film
        };
        let n = s.sample_count;
        let a = run(2 * n + 3, 0, Some(1));
        let b = run(2 * n + 3, 0, Some(2));
        assert_eq!(a.sum, b.sum, "{name}: threads");
        // pieces that cut through a pass
        let mut parts = run(n / 2, 0, None);
        parts.add(&run(n + 1, (n / 2) as u64, None));
        parts.add(&run(
            2 * n + 3 - n / 2 - n - 1,
            (n / 2 + n + 1) as u64,
            None,
        ));
        for (x, y) in a.sum.iter().zip(&parts.sum) {
            for c in 0..3 {
                assert!(
                    (x[c] - y[c]).abs() <= 1e-12 * x[c].abs().max(1.0),
                    "{name}: pieces"
                );
            }
        }
    }
}

/// `--spp` sets the points per pass as Mitsuba's render(spp) does (rounded, with a warning),
/// and a resumed render keeps the checkpoint's passes: `--resume --spp 18` after an 8-spp
/// stratified render (rounded to 9) is two passes of 9, not a pass of 25.
#[test]
fn cli_rounds_spp_and_resume_keeps_the_passes() {
    use std::process::Command;
    let dir = std::env::temp_dir().join(format!("penumbra-samplers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let xml = std::fs::read_to_string(repo_path("scenes/cornell-box.xml"))
        .unwrap()
        .replace(
            r#"<sampler type="independent">"#,
            r#"<sampler type="stratified">"#,
        );
    let scene_path = dir.join("stratified.xml");
    std::fs::write(&scene_path, xml).unwrap();
    let (ckpt, out) = (dir.join("r.ckpt"), dir.join("r.exr"));
    let run = |spp: &str, resume: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_penumbra"));
        c.arg("render")
            .arg(&scene_path)
            .args(["-D", "res=16", "--seed", "4", "--quiet", "--spp", spp])
            .arg("--checkpoint")
            .arg(&ckpt)
            .arg("-o")
            .arg(&out);
        if resume {
            c.arg("--resume");
        }
        c.output().unwrap()
    };
    let first = run("8", false);
    assert!(first.status.success());
    let err = String::from_utf8_lossy(&first.stderr);
    assert!(
        err.contains("the stratified sampler rounds sample_count 8 to 9 (--spp)"),
        "{err}"
    );
    assert_eq!(exr::read(&out).unwrap().spp(), Some(9.0));
    assert!(run("18", true).status.success());
    let resumed = exr::read(&out).unwrap();
    assert_eq!(resumed.spp(), Some(18.0));

    let scene = Job::load(&scene_path, &[("res".into(), "16".into())]).unwrap();
    let pass = |first_sample| {
        scene
            .render(
                &RenderSettings {
                    spp: 9,
                    first_sample,
                    seed: 4,
                    threads: None,
                    sampler: Some(sampler("stratified", 9)),
                },
                &|_, _| {},
            )
            .unwrap()
            .film
    };
    let mut expected = pass(0);
    expected.add(&pass(9));
    for (a, b) in expected.image().iter().zip(&resumed.rgb) {
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() <= 1e-6 * a[c].abs().max(1e-3),
                "{a:?} vs {b:?}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
