//! Mitsuba 3's render regression suite in spectral mode (issue 43): every scene rendered with
//! `--mode spectral` and judged, by Mitsuba's own rule (`penumbra::study::suite`), against
//! Mitsuba's spectral references (`<name>_ref_spectral.exr`, scalar_spectral), plus an image
//! mean test (Šidák over the 123 scene-channels) against **Mitsuba 3.9.1's own mean**: the
//! mean of 8 llvm_ad_spectral renders at the suite's sample count, recorded with its standard
//! error in validation/mitsuba-suite/spectral-means.txt by validation/suite-means/suite_means.py.
//! The spectral references themselves are not the truth for the mean: Mitsuba 3.9.1 does not
//! reproduce some of them (its own renders sit up to 8 of their standard errors off, e.g.
//! test_mesh_attributes_3_vertex, test_hetero_sigmat, test_homo_spectral_sigmat), so one
//! render of an unbiased renderer lands 2-3 of its standard errors off them and fails now and
//! then. The per-pixel rule keeps Mitsuba's references, as Mitsuba's own test does.
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
use penumbra::study::stats::{normal_critical_z, normal_two_sided_p, sidak};
use penumbra::study::suite::Judgement;
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
    let means = mitsuba_means(&root.join("spectral-means.txt"));
    // One-sided quantile: the controls' power 1 − sidak(0.05, 123).
    let z_power = normal_critical_z(2.0 * sidak(0.05, 3 * scenes.len()));
    let mut controls = 0;
    let mut failures = Vec::new();
    let mut judged = Vec::new();
    for s in &scenes {
        match suite::run(s, None) {
            Outcome::Judged(j) => {
                if !j.passed {
                    failures.push(format!(
                        "{} fails Mitsuba's test: {:.2}% of pixel-channels pass",
                        s.name,
                        100.0 * j.pass_fraction
                    ));
                }
                let Some(truth) = means.iter().find(|m| m.0 == s.name) else {
                    failures.push(format!("{} has no recorded Mitsuba mean", s.name));
                    continue;
                };
                println!(
                    "{:<62} {}  mean z vs Mitsuba 3.9.1 {:+.2} / {:+.2} / {:+.2}  {} spp  {:.2} s",
                    s.name,
                    j.summary(),
                    mean_z(&j, truth, 0, 1.0),
                    mean_z(&j, truth, 1, 1.0),
                    mean_z(&j, truth, 2, 1.0),
                    j.spp,
                    j.seconds
                );
                for c in 0..3 {
                    let z = mean_z(&j, truth, c, 1.0);
                    if normal_two_sided_p(z.abs()) <= alpha {
                        failures.push(format!(
                            "{} channel {c}: image mean {:+.3}% off Mitsuba 3.9.1's, z = {z:.2}",
                            s.name,
                            100.0 * (render_mean(&j, c) / truth.1[c] - 1.0),
                        ));
                    }
                    // Negative control: where the test sees 1% with a power of 1 − β, β
                    // Šidák-corrected to 5% over the 123 channels (so that all the controls
                    // hold together with 95% probability, not each one), the render x 1.01
                    // must fail it.
                    let se = combined_se(&j, truth, c);
                    if 0.01 * truth.1[c].abs() / se >= normal_critical_z(alpha) + z_power {
                        controls += 1;
                        let bright = mean_z(&j, truth, c, 1.01);
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
        let truth = means.iter().find(|m| m.0 == s.name).expect("checked above");
        let caught = !r.passed
            || (0..3).any(|c| normal_two_sided_p(mean_z(&r, truth, c, 1.0).abs()) <= alpha);
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

/// Mitsuba 3.9.1's image mean of one scene: (name, mean, standard error) per channel.
type MitsubaMean = (String, [f64; 3], [f64; 3]);

/// The `scene | mean | se | reference mean | z` lines of validation/suite-means/suite_means.py.
fn mitsuba_means(path: &Path) -> Vec<MitsubaMean> {
    let text = std::fs::read_to_string(path).expect("the recorded means are in the repository");
    let three = |f: &str| -> [f64; 3] {
        let v: Vec<f64> = f.split_whitespace().map(|x| x.parse().unwrap()).collect();
        [v[0], v[1], v[2]]
    };
    text.lines()
        .filter(|l| !l.starts_with('#') && l.contains('|'))
        .map(|l| {
            let f: Vec<&str> = l.split('|').map(str::trim).collect();
            (f[0].to_string(), three(f[1]), three(f[2]))
        })
        .collect()
}

/// The render's image mean in channel `c`.
fn render_mean(j: &Judgement, c: usize) -> f64 {
    j.reference_mean[c] * (1.0 + j.mean_rel_diff[c])
}

/// The standard error of (render mean − Mitsuba's mean): both estimates' in quadrature.
fn combined_se(j: &Judgement, truth: &MitsubaMean, c: usize) -> f64 {
    (j.mean_se[c].powi(2) + truth.2[c].powi(2)).sqrt()
}

/// z of the render's mean times `k` against Mitsuba's mean.
fn mean_z(j: &Judgement, truth: &MitsubaMean, c: usize, k: f64) -> f64 {
    (k * render_mean(j, c) - truth.1[c]) / combined_se(j, truth, c)
}
