//! Mitsuba 3's render regression suite in spectral mode (issue 43): every scene rendered with
//! `--mode spectral` and judged, by Mitsuba's own rule (`penumbra::study::suite`), against
//! Mitsuba's spectral references (`<name>_ref_spectral.exr`, scalar_spectral), plus the image
//! mean test of tests/mitsuba_suite.rs (Šidák over the 123 scene-channels).
//!
//! Every one of the 41 scenes must render and pass: media (volpath, volpathmis, spectral σt
//! from constants and grids) and the particle tracer included; a refusal is a failure. Negative controls: the mean test must flag the render × 1.01 wherever
//! its power to see 1% is at least 95% (as tests/mitsuba_suite.rs), and each judged scene
//! rendered in RGB mode against the same spectral reference must fail the checks wherever the
//! RGB render's mean lies more than 8 standard errors from the spectral render's (the
//! difference the issue describes; validation/scenes.toml's spectral-mitsuba-cbox resolves it
//! too).
//!
//! Full tier (`cargo test --release -- --ignored`): the suite's sample budget takes seconds
//! per scene.

use penumbra::spectrum::Mode;
use penumbra::study::stats::{normal_two_sided_p, sidak};
use penumbra::study::suite::{self, Outcome, SuiteScene};
use std::path::Path;

#[test]
#[ignore = "full tier: cargo test --release -- --ignored"]
fn mitsuba_suite_in_spectral_mode() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/mitsuba-suite");
    let scenes = suite::discover(&root, Mode::Spectral).expect("the suite is in the repository");
    assert_eq!(scenes.len(), 41, "Mitsuba's suite has 41 scenes");
    assert!(
        scenes
            .iter()
            .all(|s| s.reference.exists() && s.variance.exists()),
        "every scene has its spectral reference and variance"
    );
    let alpha = sidak(suite::SIGNIFICANCE, 3 * scenes.len());
    let mut controls = 0;
    let mut failures = Vec::new();
    let mut judged = Vec::new();
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
                if !j.passed {
                    failures.push(format!(
                        "{} fails Mitsuba's test: {:.2}% of pixel-channels pass",
                        s.name,
                        100.0 * j.pass_fraction
                    ));
                }
                for c in 0..3 {
                    if normal_two_sided_p(j.mean_z[c].abs()) <= alpha {
                        failures.push(format!(
                            "{} channel {c}: image mean {:+.3}% off the reference, z = {:.2}",
                            s.name,
                            100.0 * j.mean_rel_diff[c],
                            j.mean_z[c]
                        ));
                    }
                    if let Some(bright) = j.scaled_mean_z(c, 1.01, alpha) {
                        controls += 1;
                        if normal_two_sided_p(bright.abs()) > alpha {
                            failures.push(format!(
                                "{} channel {c}: the render x 1.01 passes the mean test (z = {bright:.2})",
                                s.name
                            ));
                        }
                    }
                }
                judged.push((s.clone(), j));
            }
            Outcome::Unsupported(e) => {
                println!("{:<62} refused: {e}", s.name);
                failures.push(format!("{} does not render in spectral mode: {e}", s.name))
            }
        }
    }
    println!("spectral mode: {} judged of {}", judged.len(), scenes.len());
    if judged.len() != scenes.len() {
        failures.push(format!(
            "only {} of {} scenes were judged",
            judged.len(),
            scenes.len()
        ));
    }
    // Negative control: RGB mode against the spectral references.
    let mut resolvable = 0;
    for (s, j) in &judged {
        let rgb = SuiteScene {
            mode: Mode::Rgb,
            ..s.clone()
        };
        let Outcome::Judged(r) = suite::run(&rgb, None) else {
            failures.push(format!("{} does not render in RGB mode", s.name));
            continue;
        };
        let sigmas = (0..3)
            .map(|c| {
                ((r.mean_rel_diff[c] - j.mean_rel_diff[c]) * j.reference_mean[c]).abs()
                    / j.mean_se[c]
            })
            .fold(0.0, f64::max);
        let caught = !r.passed || (0..3).any(|c| normal_two_sided_p(r.mean_z[c].abs()) <= alpha);
        println!(
            "{:<62} RGB mode: {}  mean {:+.3}% / {:+.3}% / {:+.3}%, {sigmas:.1} se from spectral: {}",
            s.name,
            r.summary(),
            100.0 * r.mean_rel_diff[0],
            100.0 * r.mean_rel_diff[1],
            100.0 * r.mean_rel_diff[2],
            if caught { "caught" } else { "not caught" }
        );
        if sigmas > 8.0 {
            resolvable += 1;
            if !caught {
                failures.push(format!(
                    "{}: the RGB render ({sigmas:.1} se from the spectral one) passes the spectral checks",
                    s.name
                ));
            }
        }
    }
    println!(
        "controls: x 1.01 applies to {controls} scene-channels; RGB mode resolvable on {resolvable} scenes"
    );
    assert!(controls > 0, "the x 1.01 control applied nowhere");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
