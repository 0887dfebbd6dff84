//! The fast subset of the validation study (`cargo run --release --bin validate` runs the
//! full one): every landed scene of validation/scenes.toml against its Mitsuba 3.9.1
//! reference, on a short ladder (1, 4, ... test_spp spp): the per-pixel z-test and the image
//! mean on the last image, and the convergence slope over the ladder. New scenes are
//! picked up when they are flipped to "landed" in the list.
//!
//! Also: the checks reject a wrong reference (so they can fail), and the slope fit and the
//! noise-floor rule on synthetic data with known answers.

mod common;
use common::repo_path;
use penumbra::film::{Film, FilmTile, Filter};
use penumbra::study::convergence::{
    fit_log_log, fit_slope, reference_noise_floor, spp_ladder, FLOOR_FACTOR, MIN_FIT_STEPS,
};
use penumbra::study::validation::{
    load_scene_list, mean_check, parse_scene_list, study, validate_scene, Reference, Status,
    ValidationScene, SLOPE_TOLERANCE,
};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// Seed of penumbra's renders in these tests (fixed: the tests are deterministic).
const SEED: u64 = 0x7e57;

#[test]
fn landed_scenes_match_mitsuba() {
    let root = repo_path("");
    let list = load_scene_list(&root).expect("scene list");
    let landed: Vec<_> = list.iter().filter(|s| s.is_landed()).collect();
    assert!(!landed.is_empty(), "no landed scene in the list");
    let mut failures = Vec::new();
    let mut controls = Vec::new();
    for entry in landed {
        let steps = spp_ladder(entry.test_spp);
        let r = validate_scene(&root, entry, &steps, SEED, None, None, &mut |_| {})
            .unwrap_or_else(|e| panic!("{}: {e}", entry.name));
        // Light-tracing entries share their scene and reference with a path-traced entry,
        // whose controls already measure what the checks resolve there.
        // Heavy-tailed scenes resolve no 1% bias at the tests' spp: no controls.
        if entry.integrator.is_none() && entry.test_checks.is_none() {
            controls.push(negative_controls(&root, entry, &r));
        }
        let last = r.study.last().expect("steps");
        eprintln!(
            "{}: {} spp, {:.2} s, RMSE {:.3e}, z-test pass {:.3}% (max |z| {:.2}), mean worst \
             {:.2} se / {:.3}%, slope {:?} over {} steps (floor {:.2e})",
            entry.name,
            last.spp,
            last.seconds,
            last.metrics.rmse,
            100.0 * r.study.z.pass_rate(),
            r.study.z.z_max,
            r.study.mean.max_sigmas(),
            100.0 * r.study.mean.max_relative(),
            r.study.slope.slope(),
            r.study.slope.used,
            r.study.slope.floor
        );
        assert_eq!(r.study.ladder.stats.nonfinite, 0, "{}", entry.name);
        // Heavy-tailed scenes assert the image mean only, or nothing (the list says why).
        let checks = entry.test_checks.as_deref().unwrap_or("all");
        failures.extend(
            r.study
                .failures()
                .into_iter()
                .filter(|f| checks == "all" || (checks == "mean" && f.starts_with("check 2")))
                .map(|f| format!("{}: {f}", entry.name)),
        );
    }
    assert!(failures.is_empty(), "{failures:#?}");
    let report: Vec<String> = controls.iter().map(|c| c.line()).collect();
    eprintln!("negative controls:\n{}", report.join("\n"));
    // Every control that the test can resolve must fail the checks...
    let missed: Vec<&String> = controls
        .iter()
        .zip(&report)
        .filter(|(c, _)| c.missed())
        .map(|(_, l)| l)
        .collect();
    assert!(missed.is_empty(), "biased images passed: {missed:#?}");
    // ...and most can: the 1% scale on every scene whose mean is known to ±0.125% (8 se).
    let resolved = controls.iter().filter(|c| c.scale_resolvable).count();
    assert!(
        resolved * 4 >= controls.len() * 3,
        "only {resolved} of {} scenes resolve a 1% bias",
        controls.len()
    );
}

/// Per-scene sensitivity of checks 1-2 to a 1% bias: the last image ×1.01. The bias is
/// *resolvable* when it moves some channel's mean by more than 8 standard errors of check 2
/// (twice its 4-sigma bound, so that noise in either direction cannot hide it); every
/// resolvable bias must fail check 1 or 2. The other control, a render one bounce short, is
/// in the full tier ([`one_bounce_short_fails_the_checks`]).
struct Control {
    name: String,
    /// the ×1.01 shift in standard errors (max over channels), and whether the checks failed
    scale_sigmas: f64,
    scale_resolvable: bool,
    scale_failed: bool,
}

impl Control {
    fn missed(&self) -> bool {
        self.scale_resolvable && !self.scale_failed
    }

    fn line(&self) -> String {
        format!(
            "{:24} ×1.01 = {:5.1} se: {}",
            self.name,
            self.scale_sigmas,
            resolution_word(self.scale_resolvable, self.scale_failed)
        )
    }
}

fn resolution_word(resolvable: bool, failed: bool) -> &'static str {
    match (resolvable, failed) {
        (true, true) => "caught",
        (true, false) => "MISSED",
        (false, true) => "caught (below 8 se)",
        (false, false) => "below the test's resolution",
    }
}

/// Whether checks 1 (per-pixel z-test) or 2 (image mean) reject an image of `spp` samples.
fn checks_fail(
    rgb: &[[f32; 3]],
    var: &[[f32; 3]],
    spp: u32,
    reference: &Reference,
    filter: Filter,
) -> bool {
    use penumbra::study::validation::pixel_z_test;
    let z = pixel_z_test(rgb, var, spp as f64, reference).expect("z-test");
    !z.passed() || !mean_check(rgb, var, spp as f64, reference, filter).passed()
}

fn negative_controls(
    root: &std::path::Path,
    entry: &penumbra::study::validation::ValidationScene,
    r: &penumbra::study::validation::SceneResult,
) -> Control {
    let spp = r.study.ladder.steps.last().expect("steps").spp;
    let (rgb, var) = (
        r.study.ladder.film.image(),
        r.study.ladder.film.sample_variance(),
    );
    let filter = entry.load_job(root).expect("scene").scene.filter;
    let se = r.study.mean.channels.map(|c| c.se);
    let scale_sigmas = (0..3)
        .map(|c| (0.01 * r.study.mean.channels[c].ours).abs() / se[c])
        .fold(0.0, f64::max);
    let scaled: Vec<[f32; 3]> = rgb.iter().map(|p| p.map(|x| x * 1.01)).collect();
    let scaled_var: Vec<[f32; 3]> = var.iter().map(|p| p.map(|x| x * 1.0201)).collect();
    Control {
        name: entry.name.clone(),
        scale_sigmas,
        scale_resolvable: scale_sigmas > 8.0,
        scale_failed: checks_fail(&scaled, &scaled_var, spp, &r.reference, filter),
    }
}

/// The full tier's control (`cargo test --release -- --ignored`): each landed path-traced
/// scene with a finite `max_depth`, rendered one bounce short at its test spp and seed,
/// must fail check 1 or 2 wherever the missing bounce moves some channel's mean by more
/// than 8 standard errors from the reference, and at least 5 scenes must resolve it. It
/// renders the scenes a second time, so the README's test command leaves it out.
#[test]
#[ignore = "full tier: cargo test --release -- --ignored"]
fn one_bounce_short_fails_the_checks() {
    use penumbra::integrator::Integrator;
    let root = repo_path("");
    let list = load_scene_list(&root).expect("scene list");
    let mut lines = Vec::new();
    let (mut resolvable, mut missed) = (0, Vec::new());
    for entry in list.iter().filter(|s| s.is_landed()) {
        // As for the ×1.01 control: light-tracing entries share a path-traced entry's
        // scene; heavy-tailed scenes resolve no bias at the tests' spp.
        if entry.integrator.is_some() || entry.test_checks.is_some() {
            continue;
        }
        let mut job = entry.load_job(&root).expect("scene");
        let max_depth = match &mut job.integrator {
            Integrator::Path(p) => &mut p.max_depth,
            Integrator::VolPath(p) => &mut p.max_depth,
            Integrator::VolPathMis(p) => &mut p.max_depth,
            Integrator::ParticleTracer(p) => &mut p.max_depth,
            Integrator::Bdpt(p) => &mut p.max_depth,
            Integrator::Sppm(p) => &mut p.max_depth,
            Integrator::Whitted(p) => &mut p.max_depth,
            Integrator::Direct(_) | Integrator::Aov(_) | Integrator::Radiosity(_) => continue,
        };
        if *max_depth == u32::MAX || *max_depth == 0 {
            continue;
        }
        *max_depth -= 1;
        let spp = *spp_ladder(entry.test_spp).last().expect("steps");
        let reference = entry.load_reference(&root).expect("reference");
        let out = common::render_scene(&job, spp, SEED, None);
        let (rgb, var) = (out.film.image(), out.film.sample_variance());
        let filter = job.scene.filter;
        let m = mean_check(&rgb, &var, spp as f64, &reference, filter);
        let sigmas = m.max_sigmas();
        let percent = 100.0 * m.max_relative();
        let failed = checks_fail(&rgb, &var, spp, &reference, filter);
        if sigmas > 8.0 {
            resolvable += 1;
            if !failed {
                missed.push(entry.name.clone());
            }
        }
        lines.push(format!(
            "{:24} max_depth−1 is {percent:.2}% = {sigmas:.1} se off the reference: {}",
            entry.name,
            resolution_word(sigmas > 8.0, failed)
        ));
    }
    eprintln!("one bounce short:\n{}", lines.join("\n"));
    assert!(missed.is_empty(), "biased images passed: {missed:?}");
    assert!(
        resolvable >= 5,
        "only {resolvable} scenes resolve a missing last bounce"
    );
}

/// The Cornell box (max_depth 8) compared with the max_depth 2 reference: the missing
/// interreflection must fail every check. Guards against checks that cannot fail.
/// The spectral entries' control (issue 43): Mitsuba's cbox rendered in RGB mode against its
/// llvm_ad_spectral reference must fail checks 1 or 2 at the entry's test spp (the RGB mode's
/// image differs by about 1-2% per channel, many standard errors), while `--mode spectral`
/// passes them (landed_scenes_match_mitsuba). Seen red with the RGB render replaced by the
/// spectral one (mode left at spectral).
#[test]
fn rgb_mode_fails_the_spectral_reference() {
    let root = repo_path("");
    let list = load_scene_list(&root).expect("scene list");
    let entry = list
        .iter()
        .find(|s| s.name == "spectral-mitsuba-cbox")
        .expect("the spectral cbox entry");
    assert_eq!(entry.mode.as_deref(), Some("spectral"));
    let rgb = ValidationScene {
        mode: None,
        ..entry.clone()
    };
    let job = rgb.load_job(&root).expect("scene");
    assert_eq!(job.scene.mode, penumbra::spectrum::Mode::Rgb);
    let reference = entry.load_reference(&root).expect("reference");
    let r = study(
        &job,
        &reference,
        &spp_ladder(entry.test_spp),
        SEED,
        None,
        &mut |_| {},
    )
    .expect("study");
    eprintln!(
        "RGB mode on the spectral reference: z-test pass {:.3}%, mean worst {:.1} se / {:.3}%",
        100.0 * r.z.pass_rate(),
        r.mean.max_sigmas(),
        100.0 * r.mean.max_relative()
    );
    assert!(
        !r.z.passed() || !r.mean.passed(),
        "RGB mode passes the spectral reference"
    );
}

#[test]
fn checks_reject_the_wrong_reference() {
    let root = repo_path("");
    let list = load_scene_list(&root).expect("scene list");
    let get = |name: &str| list.iter().find(|s| s.name == name).expect(name);
    let (full, direct) = (get("cornell-box"), get("cornell-depth2"));
    let scene = full.load_job(&root).expect("scene");
    let wrong = direct.load_reference(&root).expect("reference");
    let r = study(&scene, &wrong, &spp_ladder(64), SEED, None, &mut |_| {}).expect("study");
    assert!(!r.z.passed(), "z-test passed: {:?}", r.z);
    assert!(!r.mean.passed(), "mean passed: {:?}", r.mean);
    // The indirect light is missing, a bias far above the noise: the error stops falling.
    let s = r.slope.slope().expect("slope");
    assert!(s > -0.5 + SLOPE_TOLERANCE, "slope {s}");
    assert!(!r.slope.passed(SLOPE_TOLERANCE));
}

#[test]
fn scene_list_is_consistent() {
    let root = repo_path("");
    let list = load_scene_list(&root).expect("scene list");
    for s in &list {
        if s.status == Status::Landed {
            assert!(root.join(&s.file).is_file(), "{}: no {:?}", s.name, s.file);
            assert!(
                root.join(&s.reference).is_file(),
                "{}: no reference {:?}: run validation/mitsuba/render_all.py",
                s.name,
                s.reference
            );
            assert!(
                spp_ladder(s.test_spp).len() >= MIN_FIT_STEPS,
                "{}: test_spp {} gives fewer than {MIN_FIT_STEPS} ladder steps",
                s.name,
                s.test_spp
            );
        }
    }
    // The parser refuses what would make the list ambiguous.
    let entry = |name: &str, extra: &str| {
        format!(
            "[[scene]]\nname = \"{name}\"\nfile = \"a.xml\"\nfeature = \"f\"\n\
             reference = \"r.exr\"\nreference_spp = 4\ntest_spp = 4\n{extra}\n"
        )
    };
    assert!(parse_scene_list(&entry("a", "status = \"landed\"")).is_ok());
    let twice = entry("a", "status = \"landed\"") + &entry("a", "status = \"landed\"");
    assert!(parse_scene_list(&twice).unwrap_err().contains("twice"));
    assert!(parse_scene_list(&entry("a", "status = \"pending\""))
        .unwrap_err()
        .contains("why"));
    assert!(parse_scene_list(&entry("a", "status = \"done\"")).is_err());
    assert!(parse_scene_list(&entry("a", "status = \"landed\"\ncolour = 1")).is_err());
}

#[test]
fn spp_ladder_steps() {
    assert_eq!(spp_ladder(1024), [1, 4, 16, 64, 256, 1024]);
    assert_eq!(spp_ladder(100), [1, 4, 16, 64, 100]);
    assert_eq!(spp_ladder(1), [1]);
    assert!(spp_ladder(0).is_empty());
    assert_eq!(spp_ladder(u32::MAX).len(), 17);
}

#[test]
fn slope_fit_on_exact_power_laws() {
    for (a, k) in [(3.0, -0.5), (0.02, -0.5), (1.0, -1.0), (5.0, 0.0)] {
        let pts: Vec<(f64, f64)> = (0..8)
            .map(|i| 4f64.powi(i))
            .map(|x| (x, a * x.powf(k)))
            .collect();
        let l = fit_log_log(&pts).expect("fit");
        assert!((l.slope - k).abs() < 1e-12, "{l:?}");
        assert!((l.eval(1.0) - a).abs() < 1e-12 * a.max(1.0), "{l:?}");
    }
    assert!(fit_log_log(&[(1.0, 1.0)]).is_none());
    assert!(fit_log_log(&[(2.0, 1.0), (2.0, 3.0)]).is_none());
    assert!(fit_log_log(&[(1.0, 1.0), (4.0, 0.0)]).is_none());
}

/// The floor rule on the expected curve RMSE² = σ²/n + floor²: the fit keeps exactly the
/// leading steps above 3·floor, and over them the slope stays within 0.03 of −1/2 (where
/// RMSE = 3·floor, σ²/n = 8·floor² and the floor raises the RMSE by √(9/8): 6%).
#[test]
fn floor_rule_on_the_expected_curve() {
    let sigma2 = 0.07f64;
    let floor = (sigma2 / 1024.0).sqrt(); // a 1024-spp reference of the same variance
    let pts: Vec<(f64, f64)> = spp_ladder(65536)
        .into_iter()
        .map(|n| (n as f64, (sigma2 / n as f64 + floor * floor).sqrt()))
        .collect();
    let fit = fit_slope(&pts, floor, FLOOR_FACTOR);
    // RMSE > 3 floor  <=>  1024/n + 1 > 9  <=>  n < 128: steps 1, 4, 16, 64.
    assert_eq!(fit.used, 4);
    assert_eq!(fit.total, 9);
    let s = fit.slope().expect("slope");
    assert!((s + 0.5).abs() < 0.03, "slope {s}");
    assert!(fit.passed(SLOPE_TOLERANCE));
    // All steps, floor ignored: the plateau drags the slope far from −1/2.
    let all = fit_slope(&pts, 0.0, FLOOR_FACTOR);
    assert_eq!(all.used, 9);
    assert!(!all.passed(SLOPE_TOLERANCE), "{:?}", all.slope());
    // Too few steps above the floor: no verdict of success.
    let short = fit_slope(&pts[..2], floor, FLOOR_FACTOR);
    assert_eq!(short.used, 2);
    assert!(!short.passed(SLOPE_TOLERANCE));
    // A bias as large as the noise at 64 spp flattens the curve: slope fails.
    let bias = (sigma2 / 64.0).sqrt();
    let biased: Vec<(f64, f64)> = pts
        .iter()
        .map(|&(n, r)| (n, (r * r + bias * bias).sqrt()))
        .collect();
    let fb = fit_slope(&biased, floor, FLOOR_FACTOR);
    assert_eq!(fb.used, 9);
    assert!(!fb.passed(SLOPE_TOLERANCE), "{:?}", fb.slope());
}

fn normal(rng: &mut Pcg64) -> f64 {
    // Box-Muller
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Monte Carlo images with known noise: a "truth" image, a reference with per-sample
/// variance v_ref at n_ref spp, and our image at n spp with variance v (Gaussian pixel
/// noise of the right variance). The floor estimated from the reference's variance channel
/// matches the RMSE of a perfect image; the measured RMSE follows √(v/n + floor²); the
/// slope above the floor is −1/2 ± 0.1; the image-mean check passes an unbiased image and
/// rejects a 2% brighter one.
#[test]
fn floor_and_slope_on_synthetic_images() {
    let mut rng = Pcg64::seed_from_u64(17);
    let n_pix = 64 * 64;
    let truth: Vec<[f32; 3]> = (0..n_pix)
        .map(|i| [0.2 + 0.6 * (i % 64) as f32 / 64.0, 0.3, 0.1])
        .collect();
    let v: Vec<[f32; 3]> = (0..n_pix)
        .map(|i| [0.05 + 0.1 * (i / 64) as f32 / 64.0, 0.02, 0.01])
        .collect();
    let n_ref = 16384.0;
    let noisy = |rng: &mut Pcg64, n: f64, bias: f32| -> Vec<[f32; 3]> {
        truth
            .iter()
            .zip(&v)
            .map(|(t, var)| {
                std::array::from_fn(|c| {
                    t[c] * (1.0 + bias) + (normal(rng) * (var[c] as f64 / n).sqrt()) as f32
                })
            })
            .collect()
    };
    let reference = Reference {
        image: penumbra::io::exr::RgbImage {
            width: 64,
            height: 64,
            rgb: noisy(&mut rng, n_ref, 0.0),
            variance: Some(v.clone()),
            attributes: Default::default(),
        },
        spp: n_ref as u32,
        mitsuba_version: None,
        variant: None,
        render_seconds: None,
    };
    let floor = reference_noise_floor(&v, n_ref);
    assert!((floor - reference.noise_floor()).abs() < 1e-15);
    // A perfect image (the truth) shows the floor as its RMSE, to within its sampling error.
    let perfect = penumbra::study::metrics::error_metrics(&truth, &reference.image.rgb);
    assert!(
        (perfect.rmse / floor - 1.0).abs() < 0.03,
        "{} vs {floor}",
        perfect.rmse
    );
    let mean_v = penumbra::study::convergence::mean_of(&v);
    let pts: Vec<(f64, f64)> = spp_ladder(65536)
        .into_iter()
        .map(|n| {
            let img = noisy(&mut rng, n as f64, 0.0);
            let rmse = penumbra::study::metrics::error_metrics(&img, &reference.image.rgb).rmse;
            let expected = (mean_v / n as f64 + floor * floor).sqrt();
            assert!(
                (rmse / expected - 1.0).abs() < 0.03,
                "n {n}: {rmse} vs {expected}"
            );
            (n as f64, rmse)
        })
        .collect();
    let fit = fit_slope(&pts, floor, FLOOR_FACTOR);
    assert_eq!(fit.used, 6, "{fit:?}");
    assert!(fit.passed(SLOPE_TOLERANCE), "{fit:?}");

    let n = 256.0;
    let ok = mean_check(&noisy(&mut rng, n, 0.0), &v, n, &reference, Filter::Box);
    assert!(ok.passed(), "{ok:?}");
    let bright = mean_check(&noisy(&mut rng, n, 0.02), &v, n, &reference, Filter::Box);
    assert!(!bright.passed(), "{bright:?}");
    assert!(bright.channels.iter().all(|c| c.relative() > 0.01));
}

/// Check 2's standard error is the image mean's, filter included: renders of a noisy
/// constant through a wide film filter (each sample reaches up to 9×9 pixels, so the pixels
/// are correlated), `ours` against an independent `reference`, over independent trials.
/// If the se is right, Σ z² over the trials is χ² with one degree of freedom per trial;
/// with the pixels' variances summed as if independent, it is K⁻¹ ≈ 4π (gaussian σ = 1) or
/// π (Mitsuba's default σ = ½) times too large. Two-sided at α = 10⁻³ for the pair
/// (Šidák).
#[test]
fn image_mean_standard_error_accounts_for_the_filter() {
    let (w, h) = (24usize, 24usize);
    let trials = 100;
    let alpha = 1.0 - (1.0 - 1e-3f64).powf(0.5);
    let mut rng = Pcg64::seed_from_u64(0x5e);
    let render = |rng: &mut Pcg64, filter: Filter, spp: usize| -> Film {
        let mut tile = FilmTile::new(0, 0, w, h, filter);
        for y in 0..h {
            for x in 0..w {
                for _ in 0..spp {
                    let pos = glam::Vec2::new(
                        x as f32 + rng.random::<f32>(),
                        y as f32 + rng.random::<f32>(),
                    );
                    let v = 2.0 * rng.random::<f32>();
                    tile.add_sample(pos, glam::Vec3::splat(v));
                }
            }
        }
        let mut film = Film::new(w, h, filter);
        film.merge(&tile);
        film
    };
    for filter in [Filter::Gaussian { stddev: 1.0 }, Filter::DEFAULT] {
        let mut chi2 = 0.0;
        for _ in 0..trials {
            let r = render(&mut rng, filter, 16);
            let reference = Reference {
                image: penumbra::io::exr::RgbImage {
                    width: w,
                    height: h,
                    rgb: r.image(),
                    variance: Some(r.sample_variance()),
                    attributes: Default::default(),
                },
                spp: 16,
                mitsuba_version: None,
                variant: None,
                render_seconds: None,
            };
            let ours = render(&mut rng, filter, 4);
            let m = mean_check(
                &ours.image(),
                &ours.sample_variance(),
                4.0,
                &reference,
                filter,
            );
            let c = m.channels[0];
            chi2 += (c.diff() / c.se).powi(2);
        }
        let upper = penumbra::study::stats::chi2_sf(chi2, trials as f64);
        let p = 2.0 * upper.min(1.0 - upper);
        assert!(
            p > alpha,
            "{filter:?}: Σ z² = {chi2:.1} over {trials} trials (expected {trials}), p = {p:.2e}"
        );
    }
}
