//! The lane engine (issue 42) against the scalar engine, its oracle: the same film sums, bit
//! for bit, and the same path counters, on every lane backend this processor runs (avx512,
//! avx2, portable, and the width-1 scalar instance) at 1 and 2 threads, on the Cornell box,
//! an environment-map scene, a textured scene, a thin-lens camera, a wild scene, the crop
//! window with `sample_border`, hidden emitters, `max_depth` 0 and 1, structured samplers,
//! spectral mode,
//! and a scene with every kind of light the emitter kernels handle; plus the CLI: `penumbra compare` gives RMSE 0 between `--engine scalar` and
//! `--engine lanes`, the summary line names the engine, and integrators the lane engine
//! does not cover fall back to the scalar engine and say so.

mod common;
use common::repo_path;
use penumbra::film::Film;
use penumbra::render::{render_with, Engine, EngineRan, Job, RenderOutput, RenderSettings};
use penumbra::sampler::{Sampler, SamplerKind};
use penumbra::scene::description::IntegratorDesc;
use penumbra::scene::Scene;
use penumbra::simd::Backend;
use std::process::Command;

fn load(rel: &str, defines: &[(&str, &str)], edit: impl Fn(&mut IntegratorDesc)) -> Job {
    let defines: Vec<(String, String)> = defines
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let mut desc = Scene::load_description(&repo_path(rel), &defines).expect("scene loads");
    edit(&mut desc.integrator);
    Job::build(&desc).expect("scene builds")
}

fn render(
    job: &Job,
    engine: Engine,
    spp: u32,
    threads: usize,
    sampler: Option<Sampler>,
) -> RenderOutput {
    let settings = RenderSettings {
        spp,
        seed: 7,
        threads: Some(threads),
        sampler,
        first_sample: 3,
    };
    render_with(&job.scene, &job.integrator, engine, &settings, &|_, _| {}).expect("renders")
}

/// Every sum of the two films, bit for bit.
fn assert_same_film(a: &Film, b: &Film, what: &str) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}");
    assert_eq!(a.samples, b.samples, "{what}: samples");
    let bits3 = |v: &[[f64; 3]]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
    let bits = |v: &[f64]| -> Vec<u64> { v.iter().map(|x| x.to_bits()).collect() };
    for (name, x, y) in [
        ("sum", bits3(&a.sum), bits3(&b.sum)),
        ("sum_sq", bits3(&a.sum_sq), bits3(&b.sum_sq)),
        ("sum_w2", bits3(&a.sum_w2), bits3(&b.sum_w2)),
        ("sum_sq_w2", bits3(&a.sum_sq_w2), bits3(&b.sum_sq_w2)),
        ("weight", bits(&a.weight), bits(&b.weight)),
        ("weight_sq", bits(&a.weight_sq), bits(&b.weight_sq)),
        ("weight_cube", bits(&a.weight_cube), bits(&b.weight_cube)),
    ] {
        if let Some(i) = (0..x.len()).find(|&i| x[i] != y[i]) {
            panic!(
                "{what}: {name} differs at entry {i} of {} ({} vs {})",
                x.len(),
                f64::from_bits(x[i]),
                f64::from_bits(y[i])
            );
        }
    }
}

/// The scene rendered by the scalar engine and by the lane engine on every backend this
/// processor runs, at 1 and 2 threads: identical films and counters.
fn check(name: &str, job: &Job, spp: u32, sampler: Option<Sampler>) {
    let oracle = render(job, Engine::Scalar, spp, 1, sampler);
    assert_eq!(oracle.stats.engine, EngineRan::Scalar);
    let mut backends = 0;
    for backend in Backend::all_supported() {
        backends += 1;
        for threads in [1, 2] {
            let what = format!("{name}, {backend}, {threads} thread(s)");
            let out = render(job, Engine::Lanes(Some(backend)), spp, threads, sampler);
            assert_eq!(out.stats.engine, EngineRan::Lanes(backend), "{what}");
            assert_same_film(&out.film, &oracle.film, &what);
            assert_eq!(out.stats.path, oracle.stats.path, "{what}: path counters");
            assert_eq!(out.stats.nonfinite, oracle.stats.nonfinite, "{what}");
            // The lane counters add up.
            let l = out.stats.lanes;
            assert_eq!(l.width, backend.width() as u64, "{what}");
            assert_eq!(l.by_active.iter().sum::<u64>(), l.iterations, "{what}");
            let weighted: u64 = l
                .by_active
                .iter()
                .enumerate()
                .map(|(k, &n)| k as u64 * n)
                .sum();
            assert_eq!(weighted, l.traced, "{what}");
            assert_eq!(l.by_depth.iter().sum::<u64>(), l.traced, "{what}");
            assert!(
                l.scattered <= l.traced && l.traced <= l.width * l.iterations,
                "{what}"
            );
            assert_eq!(
                l.by_active[0], 0,
                "{what}: an iteration without active lanes"
            );
        }
    }
    // Scalar and portable run everywhere; this machine (x86-64 with AVX2) runs four.
    assert!(backends >= 2);
    if cfg!(target_arch = "x86_64") && std::arch::is_x86_feature_detected!("avx2") {
        assert!(backends >= 3, "{name}: the AVX2 backend was not checked");
    }
}

/// Whether the scene renders anything (a comparison of black images proves little).
fn lit(job: &Job) -> bool {
    let out = render(job, Engine::Scalar, 1, 1, None);
    out.film.sum.iter().flatten().any(|&v| v > 0.0)
}

#[test]
fn cornell_box() {
    let job = load("scenes/cornell-box.xml", &[("res", "24")], |_| {});
    assert!(lit(&job));
    check("cornell-box", &job, 6, None);
}

#[test]
fn cornell_box_structured_samplers() {
    let job = load("scenes/cornell-box.xml", &[("res", "16")], |_| {});
    for kind in ["stratified", "zsobol", "orthogonal", "ldsampler"] {
        let (sampler, _) = Sampler::new(SamplerKind::from_name(kind).unwrap(), 4);
        check(&format!("cornell-box, {kind}"), &job, 4, Some(sampler));
    }
}

#[test]
fn envmap_textures_thinlens() {
    for scene in [
        "scenes/cornell-envmap.xml",
        "scenes/textures.xml",
        "scenes/cornell-thinlens.xml",
    ] {
        let job = load(scene, &[("res", "20")], |_| {});
        assert!(lit(&job), "{scene}");
        check(scene, &job, 4, None);
    }
}

/// Spectral mode: the lanes draw each sample's wavelengths where the scalar engine does and
/// the values are converted as it converts them, so the films are the same bit for bit on
/// Mitsuba's cbox (measured spectra), an upsampled textured scene and an environment map.
#[test]
fn spectral_mode() {
    for (scene, defines) in [
        ("scenes/mitsuba/cbox/cbox.xml", &[("res", "20")][..]),
        ("scenes/textures.xml", &[("res", "20")][..]),
        ("scenes/cornell-envmap.xml", &[("res", "20")][..]),
    ] {
        let defines: Vec<(String, String)> = defines
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        let mut desc = Scene::load_description(&repo_path(scene), &defines).expect("loads");
        desc.mode = penumbra::spectrum::Mode::Spectral;
        let job = Job::build(&desc).expect("builds");
        assert!(lit(&job), "{scene}");
        check(&format!("{scene} (spectral)"), &job, 3, None);
    }
}

/// The emitter-sampling, shadow-ray and offset kernels (step 3a) on every path they take:
/// mesh lights with and without vertex normals, a sphere light (scalar lane by lane), a
/// point light, an environment, several emitters in one packet, and the pick by
/// `sampling_weight`.
#[test]
fn emitter_kernels_on_every_kind_of_light() {
    for weight in ["1", "3"] {
        let job = load(
            "tests/data/lanes-emitters.xml",
            &[("res", "20"), ("weight", weight)],
            |_| {},
        );
        assert_eq!(job.scene.emitters.len(), 5);
        assert!(lit(&job));
        check(&format!("lanes-emitters, weight {weight}"), &job, 4, None);
    }
}

/// The surface-interaction kernel (step 3b) and its lane-by-lane fallbacks: meshes with
/// and without vertex normals and texture coordinates, flip_normals, meshes inside
/// instances (one mirrored), analytic shapes, a material varying over the surface and an
/// anisotropic one (the shading frame's tangent).
#[test]
fn surface_interactions_on_every_kind_of_hit() {
    let job = load(
        "tests/data/lanes-interactions.xml",
        &[("res", "20")],
        |_| {},
    );
    assert!(lit(&job));
    check("lanes-interactions", &job, 4, None);
}

#[test]
fn crop_window_with_sample_border() {
    let job = load("scenes/sample-border.xml", &[], |_| {});
    assert!(job.scene.sample_border > 0, "the scene samples a border");
    assert!(lit(&job));
    check("sample-border", &job, 3, None);
}

#[test]
fn wild_scene() {
    let job = load(
        "scenes/wild/bitterli-veach-mis/scene.xml",
        &[("resx", "32"), ("resy", "18"), ("integrator", "path")],
        |_| {},
    );
    assert!(matches!(
        job.integrator,
        penumbra::integrator::Integrator::Path(_)
    ));
    assert!(lit(&job));
    check("bitterli-veach-mis", &job, 4, None);
}

#[test]
fn hidden_emitters_and_short_paths() {
    let set = |depth: i64, hide: bool| {
        move |d: &mut IntegratorDesc| {
            if let IntegratorDesc::Path {
                max_depth,
                hide_emitters,
                ..
            } = d
            {
                *max_depth = depth;
                *hide_emitters = hide;
            }
        }
    };
    // camera rays pass through the light (the lane goes on tracing without a bounce)
    let job = load(
        "scenes/cornell-small-light.xml",
        &[("res", "16")],
        set(8, true),
    );
    check("cornell-small-light, hide_emitters", &job, 4, None);
    // camera rays that leave the scene see black, later escapes the environment
    // (`escape_lanes`)
    let job = load("scenes/cornell-envmap.xml", &[("res", "16")], set(8, true));
    check("cornell-envmap, hide_emitters", &job, 4, None);
    // emitters only; and no path at all (black, takes no lane)
    for depth in [1, 0] {
        let job = load(
            "scenes/cornell-box.xml",
            &[("res", "16")],
            set(depth, false),
        );
        check(&format!("cornell-box, max_depth {depth}"), &job, 4, None);
    }
}

/// Other integrators run on the scalar engine when the lane engine is asked for.
#[test]
fn other_integrators_fall_back_to_scalar() {
    let job = common::load_with_integrator("scenes/cornell-box.xml", &[("res", "16")], "whitted");
    let oracle = render(&job, Engine::Scalar, 2, 1, None);
    let out = render(&job, Engine::Lanes(None), 2, 2, None);
    assert_eq!(out.stats.engine, EngineRan::ScalarFallback("whitted"));
    assert_eq!(out.stats.lanes.iterations, 0);
    assert_same_film(&out.film, &oracle.film, "whitted on --engine lanes");
}

fn penumbra(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .output()
        .expect("runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn cli_compare_gives_rmse_zero_and_the_summary_names_the_engine() {
    let dir = std::env::temp_dir().join(format!("penumbra-lanes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = repo_path("scenes/cornell-box.xml");
    let scene = scene.to_str().unwrap();
    let path = |n: &str| dir.join(n).to_string_lossy().into_owned();
    let (a, b) = (path("scalar.exr"), path("lanes.exr"));
    let base = [
        "render",
        scene,
        "-D",
        "res=24",
        "--spp",
        "4",
        "--threads",
        "2",
    ];
    let (ok, _, err) = penumbra(&[&base[..], &["--engine", "scalar", "-o", &a]].concat());
    assert!(ok, "{err}");
    assert!(err.contains(", engine scalar, "), "{err}");
    let (ok, _, err) = penumbra(&[&base[..], &["--engine", "lanes", "-o", &b]].concat());
    assert!(ok, "{err}");
    assert!(err.contains(", engine lanes ("), "{err}");
    assert!(err.contains("lanes busy: "), "{err}");
    let (ok, json, err) = penumbra(&["compare", "--json", &b, &a]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["rmse"].as_f64(), Some(0.0), "{json}");
    assert_eq!(v["max_abs"].as_f64(), Some(0.0), "{json}");
    assert!(v["mean_a"][0].as_f64().unwrap() > 0.0, "{json}");

    // a forced backend; and the statistics JSON with the utilisation
    let (c, stats) = (path("portable.exr"), path("stats.json"));
    let (ok, _, err) = penumbra(
        &[
            &base[..],
            &["--engine", "lanes", "--lane-backend", "portable"],
            &["--stats", &stats, "-o", &c],
        ]
        .concat(),
    );
    assert!(ok, "{err}");
    assert!(err.contains("engine lanes (portable, 16 wide)"), "{err}");
    let (_, json, _) = penumbra(&["compare", "--json", &c, &a]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["rmse"].as_f64(), Some(0.0), "{json}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(s["lane_width"].as_u64(), Some(16));
    let u = s["lane_utilisation"].as_f64().unwrap();
    assert!(u > 0.0 && u <= 1.0, "{s}");
    assert_eq!(
        s["lane_iterations_by_active_lanes"]
            .as_array()
            .unwrap()
            .len(),
        17
    );

    // an integrator the lane engine does not cover
    let (ok, _, err) = penumbra(
        &[
            &base[..],
            &["--engine", "lanes", "--integrator", "whitted", "-o", &c],
        ]
        .concat(),
    );
    assert!(ok, "{err}");
    assert!(
        err.contains("engine scalar (the lane engine covers the path integrator, not whitted)"),
        "{err}"
    );

    // one clear error for a backend that does not exist, or without --engine lanes
    let (ok, _, err) = penumbra(
        &[
            &base[..],
            &["--engine", "lanes", "--lane-backend", "sse9", "-o", &c],
        ]
        .concat(),
    );
    assert!(!ok && err.contains("unknown lane backend 'sse9'"), "{err}");
    let (ok, _, err) = penumbra(&[&base[..], &["--lane-backend", "portable", "-o", &c]].concat());
    assert!(
        !ok && err.contains("--lane-backend needs --engine lanes"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
