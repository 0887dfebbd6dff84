//! The Cornell box against Mitsuba 3.9.1's reference (validation/references, 4096 spp,
//! llvm_ad_rgb, with per-pixel per-sample variance): the per-pixel z-test of Mitsuba's own
//! render regression tests, and the image mean within its standard error and within 1%.

mod common;
use common::*;
use penumbra::io::exr;
use penumbra::io::exr::RgbImage;
use penumbra::metrics::{channel_means, z_test};
use std::collections::BTreeMap;

#[test]
fn cornell_box_matches_mitsuba_reference() {
    let reference =
        exr::read(&repo_path("validation/references/cornell-box.exr")).expect("reference");
    let ref_spp = 4096.0;
    let scene = load("scenes/cornell-box.xml", &[]);
    assert_eq!(
        (scene.width, scene.height),
        (reference.width, reference.height)
    );
    let spp = 64;
    let out = render_scene(&scene, spp, 0x7e57, None);
    assert_eq!(out.stats.nonfinite, 0);
    let ours = RgbImage {
        width: scene.width,
        height: scene.height,
        rgb: out.film.image(),
        variance: Some(out.film.sample_variance()),
        attributes: BTreeMap::new(),
    };
    let t = z_test(&ours, spp as f64, &reference, ref_spp, 0.01).expect("variances");
    assert!(
        t.passed(),
        "z-test: {} of {} pixel-channels fail (|z| > {:.2}); max |z| {:.2}",
        t.failures,
        t.tests,
        t.z_critical,
        t.z_max
    );
    // Global mean: the pixel means are independent, so the standard error of the image mean
    // is sqrt(Σ var_i / spp) / N, for both images.
    let (m_ours, m_ref) = (channel_means(&ours.rgb), channel_means(&reference.rgb));
    let n = ours.rgb.len() as f64;
    let vref = reference.variance.as_ref().unwrap();
    for c in 0..3 {
        let var_mean =
            |v: &[[f32; 3]], spp: f64| v.iter().map(|p| p[c] as f64).sum::<f64>() / spp / (n * n);
        let se = (var_mean(ours.variance.as_ref().unwrap(), spp as f64) + var_mean(vref, ref_spp))
            .sqrt();
        let d = (m_ours[c] - m_ref[c]).abs();
        assert!(
            d < 4.0 * se,
            "channel {c}: |{} - {}| = {d} > 4 se = {}",
            m_ours[c],
            m_ref[c],
            4.0 * se
        );
        assert!(d < 0.01 * m_ref[c], "channel {c}: more than 1% off");
    }
}
