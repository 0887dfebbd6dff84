//! Validation scenes for the thin lens, a small bright light, a sphere light (with a spot
//! light), an environment map and Mitsuba's default gaussian filter, each against its
//! Mitsuba 3.9.1 reference (validation/references, 128x128, 4096 spp, llvm_ad_rgb, rendered
//! by validation/mitsuba/render_reference.py with per-sample-equivalent variance channels):
//! the per-pixel z-test of Mitsuba's render regression tests (Šidák-corrected α = 0.01,
//! ≥ 99.75% of pixel-channels passing) and the image mean within 4 standard errors and 1%.

mod common;
use common::*;
use penumbra::io::exr;
use penumbra::io::exr::RgbImage;
use penumbra::metrics::{channel_means, z_test};
use penumbra::scene::Scene;
use std::collections::BTreeMap;

const REF_SPP: f64 = 4096.0;

/// Σ over pixels of variance / K: the per-sample variance before filtering (K is the
/// filter's per-pixel variance factor, 1 for the box filter), for the standard error of
/// the image mean. Neighbouring pixels of a filtered image share samples, so their values
/// are correlated; the image mean is still (nearly) the plain mean of all samples, whose
/// variance is mean(σ²) / (N · spp).
fn unfiltered_variance_sum(scene: &Scene, var: &[[f32; 3]], c: usize) -> f64 {
    let (w, h) = (scene.width, scene.height);
    (0..w * h)
        .map(|i| {
            let k = scene.filter.variance_factor_1d(i % w, w)
                * scene.filter.variance_factor_1d(i / w, h);
            var[i][c] as f64 / k
        })
        .sum()
}

/// Renders `scene_file` at 128x128 and `spp`, and checks it against its reference; with
/// `scale` ≠ 1 the rendered radiance is multiplied by it first (a deliberately wrong
/// render), and the function returns whether every check passed instead of asserting.
fn check(scene_file: &str, reference: &str, spp: u32, seed: u64, scale: f32) -> bool {
    let reference = exr::read(&repo_path(reference)).expect("reference");
    let scene = load(scene_file, &[("res", "128")]);
    assert_eq!(
        (scene.width, scene.height),
        (reference.width, reference.height)
    );
    let start = std::time::Instant::now();
    let out = render_scene(&scene, spp, seed, None);
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(out.stats.nonfinite, 0);
    let ours = RgbImage {
        width: scene.width,
        height: scene.height,
        rgb: out
            .film
            .image()
            .into_iter()
            .map(|p| p.map(|x| x * scale))
            .collect(),
        variance: Some(
            out.film
                .sample_variance()
                .into_iter()
                .map(|p| p.map(|x| x * scale * scale))
                .collect(),
        ),
        attributes: BTreeMap::new(),
    };
    let t = z_test(&ours, spp as f64, &reference, REF_SPP, 0.01).expect("variances");
    let (m_ours, m_ref) = (channel_means(&ours.rgb), channel_means(&reference.rgb));
    let n = ours.rgb.len() as f64;
    let mut ok = t.passed();
    let mut report = format!(
        "{scene_file} x{scale}: {spp} spp in {seconds:.1} s; z-test {} of {} pixel-channels \
         fail (|z| > {:.2}), pass rate {:.4}, max |z| {:.2}; means",
        t.failures,
        t.tests,
        t.z_critical,
        t.pass_rate(),
        t.z_max
    );
    for c in 0..3 {
        let var_ours = unfiltered_variance_sum(&scene, ours.variance.as_ref().unwrap(), c)
            / spp as f64
            / (n * n);
        let var_ref =
            unfiltered_variance_sum(&scene, reference.variance.as_ref().unwrap(), c) / REF_SPP
                / (n * n);
        let se = (var_ours + var_ref).sqrt();
        let d = (m_ours[c] - m_ref[c]).abs();
        report += &format!(
            " [{:.5} vs {:.5}: {:.2} se, {:.3}%]",
            m_ours[c],
            m_ref[c],
            d / se,
            100.0 * d / m_ref[c]
        );
        ok &= d < 4.0 * se && d < 0.01 * m_ref[c];
    }
    eprintln!("{report}");
    if scale == 1.0 {
        assert!(ok, "{report}");
    }
    ok
}

#[test]
fn cornell_thinlens_matches_mitsuba() {
    check(
        "scenes/cornell-thinlens.xml",
        "validation/references/cornell-thinlens.exr",
        spp(64),
        0x7e57,
        1.0,
    );
}

#[test]
fn cornell_small_light_matches_mitsuba() {
    check(
        "scenes/cornell-small-light.xml",
        "validation/references/cornell-small-light.exr",
        spp(64),
        0x7e57,
        1.0,
    );
}

#[test]
fn cornell_sphere_light_matches_mitsuba() {
    check(
        "scenes/cornell-sphere-light.xml",
        "validation/references/cornell-sphere-light.exr",
        spp(64),
        0x7e57,
        1.0,
    );
}

#[test]
fn cornell_envmap_matches_mitsuba() {
    check(
        "scenes/cornell-envmap.xml",
        "validation/references/cornell-envmap.exr",
        spp(64),
        0x7e57,
        1.0,
    );
}

#[test]
fn cornell_gaussian_matches_mitsuba_and_a_wrong_render_fails() {
    check(
        "scenes/cornell-gaussian.xml",
        "validation/references/cornell-gaussian.exr",
        spp(64),
        0x7e57,
        1.0,
    );
    // The same render with radiance x1.03 must fail.
    assert!(!check(
        "scenes/cornell-gaussian.xml",
        "validation/references/cornell-gaussian.exr",
        spp(64),
        0x7e57,
        1.03,
    ));
}

/// The test's spp, or PENUMBRA_VALIDATION_SPP for experiments.
fn spp(default: u32) -> u32 {
    std::env::var("PENUMBRA_VALIDATION_SPP")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}
