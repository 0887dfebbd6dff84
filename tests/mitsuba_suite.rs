//! Mitsuba 3's own render regression suite (`validation/mitsuba-suite/`), judged by Mitsuba's
//! own acceptance rule (`penumbra::study::suite`): spp = 2e6 / pixels, seed 0, per-pixel
//! z-test in XYZ against the reference's variance, Šidák α = 0.01, at least 99.75% of the
//! pixel-channels passing.
//!
//! Beyond Mitsuba's rule, each scene's image mean per channel is z-tested against the
//! reference's (standard error from the per-sample variances, Šidák over the 123
//! scene-channels), with a × 1.01 negative control wherever that test has the power to see
//! 1%.
//!
//! Every scene of the suite is run and reported (pass, fail, or the first unsupported
//! construct, printed with `--nocapture`), and every scene must pass: the 12 participating
//! media scenes (volpath, volpathmis) and the particle tracer's (`ptracer`) included.

use penumbra::study::stats::{normal_two_sided_p, sidak};

/// Scene-channels where Mitsuba 3.9.1 itself is off the suite's reference: (scene, channel,
/// Mitsuba's relative difference of the image mean), measured with scalar_rgb at the suite's
/// spp and seed 0 by validation/suite-means/mitsuba_means.py (z −11.96, −23.75, −4.43,
/// −8.87: the references' red is ~0.1% above what 3.9.1 renders under a constant emitter or
/// projector). There penumbra's mean is tested against Mitsuba's, with the standard error of
/// both renders (√2 × the render's).
const MITSUBA_OFFSETS: &[(&str, usize, f64)] = &[
    ("bsdf_spheres/test_constant_path", 0, -0.00100),
    ("orthographic_sensor/test_orthographic_path", 0, -0.00098),
    ("projector/test_projector_constant_direct", 0, -0.00077),
    ("various_shapes/test_various_shapes_path", 0, -0.00083),
];
use penumbra::study::suite::{self, Outcome};
use std::path::Path;

#[test]
fn mitsuba_regression_suite() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/mitsuba-suite");
    let scenes = suite::discover(&root).expect("the suite is in the repository");
    assert_eq!(scenes.len(), 41, "Mitsuba's suite has 41 scenes");
    let ptracer = scenes
        .iter()
        .filter(|s| s.name.ends_with("_ptracer"))
        .count();
    assert_eq!(ptracer, 1, "the suite has one particle-tracer scene");
    let media = scenes
        .iter()
        .filter(|s| s.name.starts_with("participating_media/"))
        .count();
    assert_eq!(media, 12, "the suite has 12 participating-media scenes");
    let mut failures = Vec::new();
    // The image mean, per scene and channel, against the reference's: a z-test with the
    // standard error from the per-sample variances, Šidák-corrected over the 41 × 3 tests
    // (issue 44: Mitsuba's per-pixel rule alone passed a −15.5% medium bug at 92.1%).
    let alpha = sidak(suite::SIGNIFICANCE, 3 * scenes.len());
    // Negative control: the mean test must flag the render × 1.01 wherever its power to
    // see a 1% bias is at least 95% (|0.01 mean| / se ≥ z_α + 1.645).
    let z_alpha = (1..200_000)
        .map(|i| i as f64 * 1e-4)
        .find(|z| normal_two_sided_p(*z) <= alpha)
        .unwrap_or(10.0);
    let mut controls = 0;
    for s in &scenes {
        match suite::run(s, None) {
            Outcome::Judged(j) => {
                println!(
                    "{:<62} {}  mean z {:+.2} / {:+.2} / {:+.2}  {} spp  {:.2} s",
                    s.name,
                    j.summary(),
                    j.mean_z[0],
                    j.mean_z[1],
                    j.mean_z[2],
                    j.spp,
                    j.seconds
                );
                for c in 0..3 {
                    let offset = MITSUBA_OFFSETS
                        .iter()
                        .find(|(n, ch, _)| *n == s.name && *ch == c);
                    let z = match offset {
                        None => j.mean_z[c],
                        Some((_, _, rel)) => {
                            (j.mean_rel_diff[c] - rel) * j.reference_mean[c].abs()
                                / (std::f64::consts::SQRT_2 * j.mean_se[c])
                        }
                    };
                    // NaN fails: p is NaN, not > α.
                    let passes = normal_two_sided_p(z.abs()) > alpha;
                    if !passes {
                        failures.push(format!(
                            "{} channel {c}: image mean {:+.3}% off the reference{}, z = {z:.2}",
                            s.name,
                            100.0 * j.mean_rel_diff[c],
                            if offset.is_some() {
                                " (Mitsuba's own offset removed)"
                            } else {
                                ""
                            },
                        ));
                    }
                    let shift = 0.01 * j.reference_mean[c].abs() / j.mean_se[c];
                    if shift >= z_alpha + 1.645 {
                        controls += 1;
                        let bright = j.mean_z[c]
                            + 0.01 * j.reference_mean[c] * (1.0 + j.mean_rel_diff[c])
                                / j.mean_se[c];
                        if normal_two_sided_p(bright.abs()) > alpha {
                            failures.push(format!(
                                "{} channel {c}: the render x 1.01 passes the mean test (z = {bright:.2})",
                                s.name
                            ));
                        }
                    }
                }
                if !j.passed {
                    failures.push(format!(
                        "{} fails Mitsuba's test: {:.2}% of pixel-channels pass",
                        s.name,
                        100.0 * j.pass_fraction
                    ));
                }
            }
            Outcome::Unsupported(e) => {
                println!("{:<62} unsupported: {e}", s.name);
                failures.push(format!("{} does not load: {e}", s.name));
            }
        }
    }
    println!("mean test: z_alpha {z_alpha:.2}; the x 1.01 control applies to {controls} of {} scene-channels", 3 * scenes.len());
    assert!(controls > 0, "the x 1.01 control applied nowhere");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
