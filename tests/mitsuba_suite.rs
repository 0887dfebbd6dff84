//! Mitsuba 3's own render regression suite (`validation/mitsuba-suite/`), judged by Mitsuba's
//! own acceptance rule (`penumbra::study::suite`): spp = 2e6 / pixels, seed 0, per-pixel
//! z-test in XYZ against the reference's variance, Šidák α = 0.01, at least 99.75% of the
//! pixel-channels passing.
//!
//! Beyond Mitsuba's rule, each scene's image mean per channel is z-tested against the
//! reference's (standard error from the per-sample variances, Šidák over the 123
//! scene-channels), with a × 1.01 negative control wherever that test has the power to see
//! 1%, and a second negative control as tests/validation.rs has: every scene with a finite
//! max_depth is rendered again one bounce short (max_depth − 1, same spp and seed), and
//! wherever that moves the image mean by more than 8 standard errors it must fail the
//! checks (Mitsuba's rule or the mean test).
//!
//! The suite takes minutes on 2 cores (its media scenes 10–25 s each), twice that with the
//! one-bounce-short renders: full tier.
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
use penumbra::study::suite::{self, Judgement, Outcome};
use std::path::Path;

/// The image mean test of one judged render, per channel: the z against the reference (or,
/// where Mitsuba itself is off the reference, against Mitsuba's mean), and whether it
/// passes at `alpha`.
fn mean_test(name: &str, j: &Judgement, alpha: f64) -> [(f64, bool, bool); 3] {
    std::array::from_fn(|c| {
        let offset = MITSUBA_OFFSETS
            .iter()
            .find(|(n, ch, _)| *n == name && *ch == c);
        let z = match offset {
            None => j.mean_z[c],
            Some((_, _, rel)) => {
                (j.mean_rel_diff[c] - rel) * j.reference_mean[c].abs()
                    / (std::f64::consts::SQRT_2 * j.mean_se[c])
            }
        };
        // NaN fails: p is NaN, not > α.
        (z, normal_two_sided_p(z.abs()) > alpha, offset.is_some())
    })
}

/// The scene's integrator's `max_depth` one less (a path one bounce short), or false where
/// it has none to lower (unbounded, or `direct`).
fn one_bounce_short(job: &mut penumbra::render::Job) -> bool {
    use penumbra::integrator::Integrator;
    let max_depth = match &mut job.integrator {
        Integrator::Path(p) => &mut p.max_depth,
        Integrator::VolPath(p) => &mut p.max_depth,
        Integrator::VolPathMis(p) => &mut p.max_depth,
        Integrator::ParticleTracer(p) => &mut p.max_depth,
        Integrator::Bdpt(p) => &mut p.max_depth,
        Integrator::Sppm(p) => &mut p.max_depth,
        Integrator::Whitted(p) => &mut p.max_depth,
        Integrator::Direct(_) | Integrator::Aov(_) | Integrator::Radiosity(_) => return false,
    };
    if *max_depth == u32::MAX || *max_depth == 0 {
        return false;
    }
    *max_depth -= 1;
    true
}

#[test]
#[ignore = "full tier: cargo test --release -- --ignored"]
fn mitsuba_regression_suite() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/mitsuba-suite");
    let scenes = suite::discover(&root, penumbra::spectrum::Mode::Rgb)
        .expect("the suite is in the repository");
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
    let mut controls = 0;
    // (scene, shift of the mean in standard errors, shift in %, caught by Mitsuba's rule,
    // caught by the mean test)
    let mut depth_controls: Vec<(String, f64, f64, bool, bool)> = Vec::new();
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
                for (c, (z, passes, offset)) in
                    mean_test(&s.name, &j, alpha).into_iter().enumerate()
                {
                    if !passes {
                        failures.push(format!(
                            "{} channel {c}: image mean {:+.3}% off the reference{}, z = {z:.2}",
                            s.name,
                            100.0 * j.mean_rel_diff[c],
                            if offset {
                                " (Mitsuba's own offset removed)"
                            } else {
                                ""
                            },
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
                if !j.passed {
                    failures.push(format!(
                        "{} fails Mitsuba's test: {:.2}% of pixel-channels pass",
                        s.name,
                        100.0 * j.pass_fraction
                    ));
                }
                // Negative control, as tests/validation.rs has: the same scene one bounce
                // short (max_depth − 1), same spp and seed, must fail the suite's checks
                // (Mitsuba's per-pixel rule or the mean test) wherever it moves the image
                // mean by more than 8 standard errors.
                if let Some(Outcome::Judged(d)) = suite::run_with(s, None, &mut one_bounce_short) {
                    let shifts: [f64; 3] = std::array::from_fn(|c| {
                        (j.mean_rel_diff[c] - d.mean_rel_diff[c]) * j.reference_mean[c]
                    });
                    let sigmas = (0..3)
                        .map(|c| shifts[c].abs() / j.mean_se[c])
                        .fold(0.0, f64::max);
                    let percent = 100.0
                        * (0..3)
                            .map(|c| shifts[c].abs() / j.reference_mean[c].abs().max(1e-12))
                            .fold(0.0, f64::max);
                    let by_mean = mean_test(&s.name, &d, alpha).iter().any(|t| !t.1);
                    depth_controls.push((s.name.clone(), sigmas, percent, !d.passed, by_mean));
                }
            }
            Outcome::Unsupported(e) => {
                println!("{:<62} unsupported: {e}", s.name);
                failures.push(format!("{} does not load: {e}", s.name));
            }
        }
    }
    println!(
        "mean test: z_alpha {:.2}; the x 1.01 control applies to {controls} of {} scene-channels",
        penumbra::study::stats::normal_critical_z(alpha),
        3 * scenes.len()
    );
    assert!(controls > 0, "the x 1.01 control applied nowhere");
    let mut resolvable = 0;
    for &(ref name, sigmas, percent, by_rule, by_mean) in &depth_controls {
        let verdict = match (sigmas > 8.0, by_rule || by_mean) {
            (true, true) => "caught",
            (true, false) => "MISSED",
            (false, true) => "caught (below 8 se)",
            (false, false) => "below the test's resolution",
        };
        println!(
            "{name:<62} max_depth-1 shifts the mean {percent:.2}% = {sigmas:.1} se: {verdict} (Mitsuba's rule {}, mean test {})",
            if by_rule { "fails" } else { "passes" },
            if by_mean { "fails" } else { "passes" },
        );
        if sigmas > 8.0 {
            resolvable += 1;
            if !(by_rule || by_mean) {
                failures.push(format!(
                    "{name}: one bounce short ({percent:.2}%, {sigmas:.1} se) passes the suite's checks"
                ));
            }
        }
    }
    println!(
        "one bounce short: {} scenes with a finite max_depth, {resolvable} resolvable",
        depth_controls.len()
    );
    assert!(resolvable > 0, "the max_depth - 1 control resolved nowhere");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// `suite --integrator NAME` (src/bin/suite.rs) renders each scene with its integrator
/// switched, as `render --integrator` does, and judges it against the scene's own reference:
/// the spot light's `direct` scene switched to `bdpt` passes Mitsuba's rule, and a media scene
/// switched to `bdpt` is reported unsupported with bdpt's reason (with the switch ignored it
/// renders with volpath and passes). Fast tier: the two scenes take about a second.
#[test]
fn suite_runner_switches_the_integrator() {
    let run = |scene: &str| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_suite"))
            .args(["--scene", scene, "--integrator", "bdpt", "--threads", "2"])
            .output()
            .expect("run the suite binary");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).expect("utf-8")
    };
    let spot = run("spot_light/test_spot_direct");
    assert!(
        spot.contains("| spot_light/test_spot_direct | pass ")
            && spot.contains("1 passed, 0 failed"),
        "{spot}"
    );
    let media = run("participating_media/test_homo_null_envmap");
    assert!(
        media.contains("| unsupported | the bdpt integrator does not support participating media")
            && media.contains("0 passed, 0 failed, 1 not loadable"),
        "{media}"
    );
}
