//! The bidirectional path tracer (`bdpt`) against answers known in closed form, against the
//! path tracer, strategy by strategy, and its guarantees (determinism at any thread count,
//! exact parts, one-line errors). Its MIS weights are checked against their definition in
//! the unit tests of src/integrator/bdpt.rs; its images against Mitsuba's `path` references
//! in tests/validation.rs (entries with `integrator = "bdpt"`) and the full tier below.
//!
//! Image means are compared through the means of single passes (one sample per pixel):
//! passes are independent, while the pixels of one pass are not (one light subpath splats
//! into several pixels), so the standard error is that of the mean of the passes' means.
//! z-tests at α = 0.01, Šidák-corrected over the comparisons of a test.

mod common;
use common::*;
use penumbra::integrator::Integrator;
use penumbra::render::{Job, RenderSettings};
use penumbra::scene::Scene;
use penumbra::study::stats::{normal_critical_z, sidak};

const SEED: u64 = 0xb1d1;

/// The image means of `passes` single passes (sample indices first..first + passes).
fn pass_means(job: &Job, passes: u64, first: u64, seed: u64) -> Vec<[f64; 3]> {
    (0..passes)
        .map(|k| {
            let out = job
                .render(
                    &RenderSettings {
                        spp: 1,
                        first_sample: first + k,
                        seed,
                        threads: None,
                        sampler: None,
                    },
                    &|_, _| {},
                )
                .expect("render");
            let img = out.film.image();
            let n = img.len() as f64;
            std::array::from_fn(|c| img.iter().map(|p| p[c] as f64).sum::<f64>() / n)
        })
        .collect()
}

/// The mean of `passes` passes' image means and its standard error, per channel.
fn mean_and_se(job: &Job, passes: u64, seed: u64) -> ([f64; 3], [f64; 3]) {
    let m = pass_means(job, passes, 0, seed);
    let n = m.len() as f64;
    let mean: [f64; 3] = std::array::from_fn(|c| m.iter().map(|p| p[c]).sum::<f64>() / n);
    let se = std::array::from_fn(|c| {
        let var = m.iter().map(|p| (p[c] - mean[c]).powi(2)).sum::<f64>() / (n - 1.0);
        (var / n).sqrt()
    });
    (mean, se)
}

/// A 16 x 16 view from inside a closed diffuse sphere (reflectance ρ, emitting `le`
/// inwards) with a point light of intensity I at its centre, rendered by bdpt.
/// `path` and `bdpt` render the same image mean: a two-sided z-test per channel at `z_crit`
/// (seeds SEED and SEED + 1, `passes` passes each), and a standard error of the difference
/// below `max_rel_se` of the mean (so that the test resolves a bias of a few times that).
fn assert_path_and_bdpt_agree(
    what: &str,
    path: &Job,
    bdpt: &Job,
    passes: u64,
    z_crit: f64,
    max_rel_se: f64,
) {
    let (a, sa) = mean_and_se(path, passes, SEED);
    let (b, sb) = mean_and_se(bdpt, passes, SEED + 1);
    for c in 0..3 {
        let se = (sa[c].powi(2) + sb[c].powi(2)).sqrt();
        let z = (a[c] - b[c]).abs() / se;
        assert!(
            z < z_crit,
            "{what}, channel {c}: path {} bdpt {} (z = {z:.2})",
            a[c],
            b[c]
        );
        assert!(se < max_rel_se * a[c], "{what}: se {se} of {}", a[c]);
    }
}

fn furnace(max_depth: i64, rho: f64, le: f64, intensity: f64) -> Job {
    scene_from_str(&format!(
        r#"<scene version="3.0.0">
            <integrator type="bdpt"><integer name="max_depth" value="{max_depth}"/></integrator>
            <sensor type="perspective"><float name="fov" value="50"/>
                <transform name="to_world"><lookat origin="0.5, 0.2, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/>
                    <rfilter type="box"/></film></sensor>
            <shape type="sphere">
                <float name="radius" value="3"/>
                <boolean name="flip_normals" value="true"/>
                <bsdf type="diffuse"><rgb name="reflectance" value="{rho}"/></bsdf>
                <emitter type="area"><rgb name="radiance" value="{le}"/></emitter>
            </shape>
            <emitter type="point"><rgb name="intensity" value="{intensity}"/></emitter>
        </scene>"#
    ))
}

/// Inside the closed sphere every surface point has the same radiance: the point light's
/// irradiance I/9 is uniform on it and so is every bounce, so every pixel shows
/// L = Σ_{j<k} ρ^j L_e + (ρ I / 9π) Σ_{j<k−1} ρ^j with max_depth k (unbounded: Russian
/// roulette alone ends the paths). Every strategy carries part of this light (the area
/// emitter is hit, sampled and starts light subpaths; the point light is sampled and starts
/// them; every vertex is connected to the camera), so this checks the depth count, the
/// throughputs of both subpaths, Russian roulette's weights, the emitters' choice and the
/// light-tracing splats, all at once.
#[test]
fn furnace_sphere_sums_the_geometric_series() {
    let (rho, le, intensity) = (0.8f64, 1.0f64, 20.0f64);
    let direct = rho * intensity / (9.0 * std::f64::consts::PI);
    let series = |n: i64| (0..n.max(0)).map(|j| rho.powi(j as i32)).sum::<f64>();
    let cases = [
        (-1i64, (le + direct) / (1.0 - rho)),
        (4, le * series(4) + direct * series(3)),
        (2, le * series(2) + direct * series(1)),
        (1, le),
    ];
    let z_crit = normal_critical_z(sidak(0.01, cases.len() * 3));
    for (max_depth, want) in cases {
        let job = furnace(max_depth, rho, le, intensity);
        assert!(matches!(job.integrator, Integrator::Bdpt(_)));
        let (mean, se) = mean_and_se(&job, 96, SEED);
        for c in 0..3 {
            let z = (mean[c] - want).abs() / se[c];
            assert!(
                z < z_crit,
                "max_depth {max_depth}: {} vs {want} (z = {z:.2})",
                mean[c]
            );
            // Resolves a 2% error at 4 standard errors.
            assert!(
                se[c] < 5e-3 * want,
                "max_depth {max_depth}: se {} of {want}",
                se[c]
            );
        }
    }
}

/// "RR ended" is the fraction of samples whose camera subpath Russian roulette ended, as
/// `path` reports it. Inside the closed furnace sphere without a depth limit nothing else
/// ends a camera subpath, so it is exactly 1; light subpaths, also ended by roulette, are
/// not counted (when they were, the summary line said "RR ended 118.6%").
#[test]
fn russian_roulette_statistic_counts_camera_subpaths() {
    let job = furnace(-1, 0.8, 1.0, 20.0);
    let out = render_scene(&job, 4, SEED, Some(1));
    assert_eq!(out.stats.paths, 16 * 16 * 4);
    assert_eq!(out.stats.path.rr_terminated, out.stats.paths);
}

/// The diffuse Cornell box at 32 x 32 with `integrator` and max_depth `depth`, its emitters
/// hidden from the camera (so that every path has at least two segments).
fn cornell(integrator: &str, depth: i64) -> Job {
    let xml = std::fs::read_to_string(repo_path("scenes/cornell-box.xml")).expect("scene");
    let xml = xml.replace(
        r#"<integrator type="path">"#,
        &format!(r#"<integrator type="{integrator}"><boolean name="hide_emitters" value="true"/>"#),
    );
    let defines = [
        ("res".to_string(), "32".to_string()),
        ("max_depth".to_string(), depth.to_string()),
    ];
    Job::from_xml_str(&xml, &repo_path("scenes/cornell-box.xml"), &defines).expect("scene")
}

/// Each strategy (s, t) rendered alone and unweighted (`strategy_mis` false) estimates all
/// the light carried by paths of s + t vertices, where it can make every such path: in the
/// diffuse Cornell box (an area light, a pinhole camera), paths of 3 and 4 vertices. Each
/// must agree with the full estimate of those paths, the difference of full bdpt renders at
/// max_depth n − 1 and n − 2 (independent seeds). This fails for a strategy that is dropped
/// or mis-scaled (the light-tracing splats without the camera's 1/dist² or cos³θ, a
/// connection without its 1/dist²), which MIS would otherwise spread over the others.
#[test]
fn each_strategy_alone_is_unbiased() {
    let passes = 256;
    let strategies: Vec<(u32, u32)> = vec![(0, 3), (1, 2), (2, 1), (0, 4), (1, 3), (2, 2), (3, 1)];
    let z_crit = normal_critical_z(sidak(0.01, strategies.len() * 3));
    let full = |depth: i64, seed: u64| mean_and_se(&cornell("bdpt", depth), passes, seed);
    let levels: Vec<_> = (1..=3).map(|d| full(d, SEED + d as u64)).collect();
    for (s, t) in strategies {
        let n = (s + t) as usize;
        // Paths of n vertices have n − 1 segments: max_depth n − 1 minus n − 2.
        let (hi, lo) = (&levels[n - 2], &levels[n - 3]);
        let mut job = cornell("bdpt", (n - 1) as i64);
        let Integrator::Bdpt(b) = &mut job.integrator else {
            panic!("not bdpt")
        };
        b.strategy = Some((s, t));
        b.strategy_mis = false;
        let (mean, se) = mean_and_se(&job, passes, SEED + 100 + (s * 10 + t) as u64);
        for c in 0..3 {
            let want = hi.0[c] - lo.0[c];
            let se = (se[c].powi(2) + hi.1[c].powi(2) + lo.1[c].powi(2)).sqrt();
            let z = (mean[c] - want).abs() / se;
            assert!(
                z < z_crit,
                "strategy ({s}, {t}), channel {c}: {} vs {want} (z = {z:.2})",
                mean[c]
            );
            // Resolves a 20% error at 4 standard errors.
            assert!(se < 0.05 * want, "strategy ({s}, {t}): se {se} of {want}");
        }
    }
}

/// The MIS-weighted images of the strategies add up to the full image, pixel by pixel:
/// every strategy's share reaches the film once (splats included), with the same random
/// numbers.
#[test]
fn the_strategies_images_add_up_to_the_full_image() {
    for share in [1.0, 0.5] {
        strategies_images_add_up(share);
    }
}

/// (With light subpaths in a share of the samples, given to every render.)
fn strategies_images_add_up(share: f32) {
    let depth = 3;
    let with_share = |mut job: Job| {
        let Integrator::Bdpt(b) = &mut job.integrator else {
            panic!("not bdpt")
        };
        b.light_paths = Some(share);
        job
    };
    let full = with_share(cornell("bdpt", depth));
    let render = |job: &Job| render_scene(job, 4, SEED, None).film;
    let whole = render(&full);
    let mut sum = vec![[0.0f64; 3]; whole.sum.len()];
    for n in 3..=(depth + 1) as u32 {
        for s in 0..n {
            let mut job = with_share(cornell("bdpt", depth));
            let Integrator::Bdpt(b) = &mut job.integrator else {
                panic!("not bdpt")
            };
            b.strategy = Some((s, n - s));
            let film = render(&job);
            assert_eq!(film.weight, whole.weight, "({s}, {}): pixel weights", n - s);
            for (acc, x) in sum.iter_mut().zip(&film.sum) {
                for c in 0..3 {
                    acc[c] += x[c];
                }
            }
        }
    }
    // A camera sample adds its strategies' shares in f32 (a few, each rounded by 2⁻²⁴).
    for (i, (a, b)) in sum.iter().zip(&whole.sum).enumerate() {
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() <= 1e-6 * b[c].abs().max(1e-3),
                "share {share}, pixel {i}: strategies {} vs {}",
                a[c],
                b[c]
            );
        }
    }
    assert!(whole.sum.iter().any(|p| p[0] > 0.0));
}

/// `max_depth` counts as the path tracer counts it: at max_depth 1 (the light seen directly)
/// bdpt renders the path tracer's image, bit for bit (the same camera rays, ending on the
/// light); at 2 (direct light), 3, 5 and unbounded the image means agree (independent
/// seeds; the light hidden from the camera, whose edge pixels would dominate the noise).
#[test]
fn path_and_bdpt_agree_at_every_max_depth() {
    let load = |integrator: &str, depth: i64| {
        load_with_integrator(
            "scenes/cornell-box.xml",
            &[("res", "32"), ("max_depth", &depth.to_string())],
            integrator,
        )
    };
    let (a, b) = (load("path", 1), load("bdpt", 1));
    let (ia, ib) = (
        render_scene(&a, 8, SEED, None).film.image(),
        render_scene(&b, 8, SEED, None).film.image(),
    );
    assert_eq!(ia, ib, "max_depth 1");
    assert!(ia.iter().any(|p| p[0] > 1.0), "the light is in view");
    let depths = [2i64, 3, 5, -1];
    let z_crit = normal_critical_z(sidak(0.01, depths.len() * 3));
    for depth in depths {
        // Resolves a 4% error at 4 standard errors.
        assert_path_and_bdpt_agree(
            &format!("max_depth {depth}"),
            &cornell("path", depth),
            &cornell("bdpt", depth),
            128,
            z_crit,
            0.01,
        );
    }
}

/// `hide_emitters`: camera rays pass through area emitters, in bdpt as in path. A
/// rectangle light facing away from the camera hides part of a lit floor and a wall: the
/// camera sees the floor through it, and light paths reach the camera through it.
#[test]
fn hidden_emitters_are_passed_through_as_the_path_tracer_does() {
    let xml = |integrator: &str| {
        format!(
            r#"<scene version="3.0.0">
            <integrator type="{integrator}"><integer name="max_depth" value="3"/>
                <boolean name="hide_emitters" value="true"/></integrator>
            <sensor type="perspective"><float name="fov" value="60"/>
                <transform name="to_world"><lookat origin="0, 1, 3" target="0, 0.5, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/>
                    <rfilter type="box"/></film></sensor>
            <shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
                <bsdf type="diffuse"/></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="3"/><translate z="-1.5"/></transform>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.6, 0.3"/></bsdf></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="0.6"/><rotate x="1" angle="180"/><translate y="0.8" z="0.8"/></transform>
                <emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>
        </scene>"#
        )
    };
    // Every sample traces a light subpath: the light paths through the hidden emitter are
    // what this tests (the pilot would trace fewer here).
    let bdpt = xml("bdpt").replace(
        r#"<boolean name="hide_emitters" value="true"/>"#,
        r#"<boolean name="hide_emitters" value="true"/><float name="light_paths" value="1"/>"#,
    );
    let z_crit = normal_critical_z(sidak(0.01, 3));
    assert_path_and_bdpt_agree(
        "hidden emitters",
        &scene_from_str(&xml("path")),
        &scene_from_str(&bdpt),
        256,
        z_crit,
        0.01,
    );
}

/// A light subpath that cannot start (its emitter, picked at random, emits nothing) leaves
/// next-event estimation, which picks again, its share: with a black rectangle light beside
/// a lit one, bdpt agrees with path.
#[test]
fn an_empty_light_subpath_leaves_next_event_estimation_its_share() {
    let xml = |integrator: &str| {
        format!(
            r#"<scene version="3.0.0">
            <integrator type="{integrator}"><integer name="max_depth" value="3"/></integrator>
            <sensor type="perspective"><float name="fov" value="60"/>
                <transform name="to_world"><lookat origin="0, 1, 3" target="0, 0.5, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/>
                    <rfilter type="box"/></film></sensor>
            <shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
                <bsdf type="diffuse"/></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate y="2"/></transform>
                <emitter type="area"><rgb name="radiance" value="4"/></emitter></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate x="1" y="2"/></transform>
                <emitter type="area"><rgb name="radiance" value="0"/></emitter></shape>
        </scene>"#
        )
    };
    let z_crit = normal_critical_z(sidak(0.01, 3));
    assert_path_and_bdpt_agree(
        "black light beside a lit one",
        &scene_from_str(&xml("path")),
        &scene_from_str(&xml("bdpt")),
        512,
        z_crit,
        0.01,
    );
}

/// What the path tracer cannot render, bdpt does: a point light's caustic off a mirror
/// sphere onto a diffuse floor (point → mirror → floor → camera: the path tracer's floor
/// vertex cannot connect through the mirror, and its BSDF samples cannot hit a point).
/// bdpt's image exceeds path's by exactly that light, which light tracing alone renders:
/// strategy (3, 1) unweighted at max_depth 3 (the floor cannot light itself, so its paths
/// of four vertices are the caustic's). Mitsuba's path references of such scenes lack it
/// (whitted-exact: +5% for bdpt).
#[test]
fn a_point_lights_caustic_is_the_difference_to_the_path_tracer() {
    caustic_is_the_difference_to_the_path_tracer("", 256);
}

/// The same with light subpaths traced in a quarter of the samples only (`light_paths`):
/// the caustic, which only strategies s ≥ 2 make, is divided by that share and keeps its
/// brightness; the MIS weights count those strategies with the share.
#[test]
fn a_share_of_light_subpaths_keeps_the_caustic() {
    // (Four times the passes: a quarter of them carry the caustic.)
    caustic_is_the_difference_to_the_path_tracer(
        r#"<float name="light_paths" value="0.25"/>"#,
        1024,
    );
}

/// A diffuse floor, a mirror sphere and a point light above them, 24 × 24, max_depth 3:
/// the light's caustic on the floor is made by light subpaths alone (s ≥ 2).
fn caustic_scene(integrator: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
        <integrator type="{integrator}"><integer name="max_depth" value="3"/></integrator>
        <sensor type="perspective"><float name="fov" value="45"/>
            <transform name="to_world"><lookat origin="0, 2.4, 4.2" target="0, 0.4, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/>
                <rfilter type="box"/></film></sensor>
        <shape type="rectangle"><transform name="to_world"><scale value="4"/><rotate x="1" angle="-90"/></transform>
            <bsdf type="diffuse"/></shape>
        <shape type="sphere"><point name="center" x="-0.9" y="0.6" z="0"/><float name="radius" value="0.6"/>
            <bsdf type="conductor"><string name="material" value="Al"/></bsdf></shape>
        <emitter type="point"><point name="position" x="-1.5" y="3" z="2"/><rgb name="intensity" value="12"/></emitter>
    </scene>"#
    )
}

fn caustic_is_the_difference_to_the_path_tracer(bdpt_params: &str, passes: u64) {
    let xml = caustic_scene;
    let caustic = xml("bdpt").replace(
        r#"<integer name="max_depth" value="3"/>"#,
        r#"<integer name="max_depth" value="3"/><integer name="strategy_s" value="3"/>
            <integer name="strategy_t" value="1"/><boolean name="strategy_mis" value="false"/>"#,
    );
    let bdpt = xml("bdpt").replace(
        r#"<integer name="max_depth" value="3"/>"#,
        &format!(r#"<integer name="max_depth" value="3"/>{bdpt_params}"#),
    );
    let (p, sp) = mean_and_se(&scene_from_str(&xml("path")), passes, SEED);
    let (b, sb) = mean_and_se(&scene_from_str(&bdpt), passes, SEED + 1);
    let (c, sc) = mean_and_se(&scene_from_str(&caustic), passes, SEED + 2);
    let z_crit = normal_critical_z(sidak(0.01, 3));
    for k in 0..3 {
        let se = (sp[k].powi(2) + sb[k].powi(2) + sc[k].powi(2)).sqrt();
        let z = (b[k] - p[k] - c[k]).abs() / se;
        assert!(
            z < z_crit,
            "channel {k}: bdpt {} − path {} against the caustic {} (z = {z:.2})",
            b[k],
            p[k],
            c[k]
        );
        // The caustic is resolved: more than 8 standard errors of the comparison.
        assert!(c[k] > 8.0 * se, "caustic {} with se {se}", c[k]);
    }
}

/// With a share of light subpaths, the Cornell box renders the path tracer's image mean
/// (every strategy re-weighted: the box is lit by s ≤ 1 and s ≥ 2 alike).
#[test]
fn a_share_of_light_subpaths_renders_the_path_tracers_image() {
    let path = cornell("path", 4);
    let mut bdpt = cornell("bdpt", 4);
    let Integrator::Bdpt(b) = &mut bdpt.integrator else {
        panic!("not bdpt")
    };
    b.light_paths = Some(0.125);
    let z_crit = normal_critical_z(sidak(0.01, 3));
    assert_path_and_bdpt_agree(
        "Cornell box, 1/8 light subpaths",
        &path,
        &bdpt,
        256,
        z_crit,
        0.01,
    );
}

/// The pilot that chooses the share of light subpaths (`light_paths` 0): in the Cornell box
/// (128², as scenes/cornell-box.xml), lit directly and diffusely by an area light, light
/// subpaths add cost and little else, and it takes none (every path there has a
/// camera-side strategy); in the room lit through a small opening (scenes/bdpt-opening.xml)
/// they carry the light, and it takes all. Its choice and its estimates are the same at
/// any thread count (and so for every part of a render).
#[test]
fn the_pilot_takes_light_subpaths_where_they_pay() {
    use penumbra::render::{choose_light_paths, thread_pool, LIGHT_PATH_SHARES};
    let bdpt_of = |job: &Job| match &job.integrator {
        Integrator::Bdpt(b) => b.clone(),
        _ => panic!("not bdpt"),
    };
    let cornell = cornell("bdpt", 8);
    // (`light_paths` 0 asks for the pilot, as leaving it out does.)
    let auto = Job::from_xml_str(
        &std::fs::read_to_string(repo_path("scenes/cornell-box.xml"))
            .expect("scene")
            .replace(
                r#"<integrator type="path">"#,
                r#"<integrator type="bdpt"><float name="light_paths" value="0"/>"#,
            ),
        &repo_path("scenes/cornell-box.xml"),
        &[("res".to_string(), "128".to_string())],
    )
    .expect("scene");
    assert_eq!(bdpt_of(&auto).light_paths, None);
    assert_eq!(bdpt_of(&cornell).light_paths, None);
    let opening = Job::load(
        &repo_path("scenes/bdpt-opening.xml"),
        &[
            ("integrator".to_string(), "bdpt".to_string()),
            ("res".to_string(), "64".to_string()),
        ],
    )
    .expect("scene");
    let one = thread_pool(Some(1)).expect("pool");
    let two = thread_pool(Some(2)).expect("pool");
    let c1 = choose_light_paths(&auto.scene, &bdpt_of(&auto), SEED, &one);
    let c2 = choose_light_paths(&auto.scene, &bdpt_of(&auto), SEED, &two);
    assert_eq!((c1.share, &c1.variance), (c2.share, &c2.variance));
    assert!(c1.camera_side_complete, "Cornell box: {c1:?}");
    assert_eq!(c1.share, 0.0, "Cornell box: {c1:?}");
    // The variance it predicts at share 1/64 against share 1: 1.06 as measured from the
    // variance channels of 1024-spp renders (16.7M samples each; docs/bdpt.md), 1.059
    // predicted here; a pilot that re-weights contributions whose shadow rays took their
    // roulette with other weights predicts 1.35 here (2.7 with the CLI's seed).
    let at = |c: f32| {
        LIGHT_PATH_SHARES
            .iter()
            .position(|&x| x == c)
            .expect("share")
    };
    let ratio = c1.variance[at(1.0 / 64.0)] / c1.variance[at(1.0)];
    assert!(ratio < 1.2, "Cornell box: variance ratio {ratio}: {c1:?}");
    let o = choose_light_paths(&opening.scene, &bdpt_of(&opening), SEED, &two);
    assert_eq!(o.share, 1.0, "opening: {o:?}");
}

/// Share 0 (no light subpaths) only where every path has a camera-side strategy: not in a
/// scene lit by a point light, whose caustic (the light through a mirror sphere onto a
/// diffuse floor) only light subpaths make, however cheap and quiet share 0 looks there.
#[test]
fn the_pilot_keeps_light_subpaths_where_only_they_make_some_paths() {
    use penumbra::render::{choose_light_paths, thread_pool, LightPathChoice, LIGHT_PATH_SHARES};
    let k = LIGHT_PATH_SHARES.len();
    assert_eq!(LIGHT_PATH_SHARES[k - 1], 0.0);
    // Share 0 the cheapest and the quietest: chosen only where the camera side is complete.
    let choice = |complete: bool| LightPathChoice {
        share: 1.0,
        cost: (0..k).map(|i| (k - i) as f64).collect(),
        variance: vec![1.0; k],
        camera_side_complete: complete,
    };
    assert_eq!(choice(true).best(0.5), 0.0);
    assert_eq!(choice(false).best(0.0), 1.0 / 64.0);
    assert_eq!(choice(false).best(0.5), 0.5);
    // The caustic scene of the tests above, with the pilot's choice.
    let job = scene_from_str(&caustic_scene("bdpt"));
    let Integrator::Bdpt(b) = &job.integrator else {
        panic!("not bdpt")
    };
    assert!(!b.camera_side_complete(&job.scene));
    let pool = thread_pool(Some(2)).expect("pool");
    let c = choose_light_paths(&job.scene, b, SEED, &pool);
    assert!(!c.camera_side_complete && c.share > 0.0, "{c:?}");
    let resolved = b.resolved(&job.scene, SEED, 4096, &pool);
    assert!(resolved.light_share() > 0.0);
}

/// Without light subpaths (share 0, as the pilot chooses in the Cornell box at 128²) bdpt
/// renders with the path tracer, its depths and roulette and hidden emitters: the same
/// image, bit for bit; asked for the lane engine, on it (which covers the path tracer).
#[test]
fn without_light_subpaths_bdpt_renders_the_path_tracers_image() {
    let settings = RenderSettings {
        spp: 64,
        first_sample: 0,
        seed: SEED,
        threads: None,
        sampler: None,
    };
    let with = |integrator: &str, engine: penumbra::render::Engine| {
        let xml = std::fs::read_to_string(repo_path("scenes/cornell-box.xml")).expect("scene");
        let xml = xml.replace(
            r#"<integrator type="path">"#,
            &format!(
                r#"<integrator type="{integrator}"><boolean name="hide_emitters" value="true"/>
                    <integer name="rr_depth" value="2"/>"#
            ),
        );
        let defines = [
            ("res".to_string(), "32".to_string()),
            ("max_depth".to_string(), "4".to_string()),
        ];
        let mut job =
            Job::from_xml_str(&xml, &repo_path("scenes/cornell-box.xml"), &defines).expect("scene");
        if let Integrator::Bdpt(b) = &mut job.integrator {
            b.light_paths = Some(0.0);
        }
        job.engine = engine;
        job.render(&settings, &|_, _| {}).expect("renders")
    };
    use penumbra::render::{Engine, EngineRan};
    let path = with("path", Engine::Scalar);
    assert!(path.film.sum.iter().any(|p| p[0] > 0.0), "black");
    for engine in [Engine::Scalar, Engine::Lanes(None)] {
        let bdpt = with("bdpt", engine);
        assert_eq!(bdpt.stats.light_paths, Some(0.0));
        assert_eq!(
            matches!(bdpt.stats.engine, EngineRan::Lanes(_)),
            engine != Engine::Scalar,
            "{:?}",
            bdpt.stats.engine
        );
        assert!(
            path.film.sum == bdpt.film.sum && path.film.sum_sq == bdpt.film.sum_sq,
            "another image ({engine:?})"
        );
    }
}

/// Where the shading normals bend far from the geometric ones (tests/data/ptracer-shading:
/// vertex normals leaning 10° to 50°, and on top of them a normal map or a bump map), bdpt
/// renders the path tracer's image: its light subpaths evaluate the path tracer's BSDF
/// value with the directions exchanged. (An importance-mode BSDF with Veach's adjoint
/// correction, as `ptracer` uses, renders another image where Mitsuba's `normalmap` and
/// `bumpmap` perturb the frame: they have no adjoint of their own.)
#[test]
fn bent_normal_and_bump_mapped_surfaces_render_the_path_tracers_image() {
    // (file, the largest standard error allowed, relative): the normal and bump maps change
    // the image by ~0.3% when light subpaths take the importance-mode value instead.
    let files = [
        ("direct.xml", 1e-3),
        ("bounce.xml", 1e-2),
        ("normalmap.xml", 1e-3),
        ("bumpmap.xml", 1e-3),
    ];
    let z_crit = normal_critical_z(sidak(0.01, files.len() * 3));
    for (file, bound) in files {
        let rel = format!("tests/data/ptracer-shading/{file}");
        let load = |integrator: &str| load(&rel, &[("integrator", integrator), ("res", "16")]);
        assert_path_and_bdpt_agree(file, &load("path"), &load("bdpt"), 1024, z_crit, bound);
    }
}

/// The same seed gives the same image bit for bit with 1 and 2 threads, and another seed
/// another image; a render continued from where another stopped adds up to the same sums
/// (to rounding: the passes are added in another order).
#[test]
fn deterministic_at_any_thread_count() {
    let job = load_with_integrator("scenes/cornell-gaussian.xml", &[("res", "24")], "bdpt");
    let a = render_scene(&job, 6, SEED, Some(1));
    let b = render_scene(&job, 6, SEED, Some(2));
    let c = render_scene(&job, 6, SEED + 1, Some(2));
    assert_eq!(a.film.sum, b.film.sum);
    assert_eq!(a.film.sum_sq, b.film.sum_sq);
    assert_eq!(a.film.weight, b.film.weight);
    assert_ne!(a.film.sum, c.film.sum);
    assert_eq!(a.film.spp(), 6.0);
    assert_eq!(a.stats.paths, 24 * 24 * 6);
    let part = |spp, first_sample| {
        job.render(
            &RenderSettings {
                spp,
                first_sample,
                seed: SEED,
                threads: None,
                sampler: None,
            },
            &|_, _| {},
        )
        .expect("render")
    };
    let mut sum = part(2, 0).film;
    sum.add(&part(4, 2).film);
    assert_eq!(sum.spp(), 6.0);
    for (x, y) in sum.sum.iter().zip(&a.film.sum) {
        for k in 0..3 {
            assert!(
                (x[k] - y[k]).abs() <= 1e-12 * y[k].abs().max(1.0),
                "{x:?} vs {y:?}"
            );
        }
    }
}

/// `--part`s of a bdpt render merge to the render made in one process, bit for bit, with a
/// wide filter (splats across pixels) and with Mitsuba's crop window and sample border
/// (camera samples and splats beyond the window). Each scene gets a point light too, so
/// that the pilot may not leave light subpaths out (share 0 is for scenes whose every path
/// has a camera-side strategy) and every part must draw the same share of them.
#[test]
fn parts_merge_to_the_one_process_render() {
    use penumbra::progressive::{
        merge_parts, render_part, render_progressive, scene_hash, PartPlan, ProgressiveSettings,
    };
    // Parts are whole passes of pass_spp(width, height) samples: 64 at 64 x 64 px, 136 for
    // the 40 x 48 crop.
    for (rel, defines, spp, count) in [
        ("scenes/cornell-gaussian.xml", vec![("res", "64")], 130, 3),
        ("scenes/sample-border.xml", vec![], 140, 2),
    ] {
        let defines: Vec<(String, String)> = defines
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        let xml = std::fs::read_to_string(repo_path(rel))
            .expect("scene")
            .replace(
                "</scene>",
                r#"<emitter type="point"><point name="position" x="0" y="0.5" z="0"/>
                    <rgb name="intensity" value="0.5"/></emitter></scene>"#,
            );
        let mut desc =
            Scene::description_from_xml_str(&xml, &repo_path(rel), &defines).expect("loads");
        desc.use_integrator("bdpt").expect("bdpt");
        let hash = scene_hash(&desc);
        let job = Job::build(&desc).expect("builds");
        let single = render_progressive(
            &job,
            &ProgressiveSettings {
                spp,
                seed: SEED,
                threads: None,
                time_limit: None,
                target_rel_error: None,
                checkpoint: None,
                scene_hash: hash,
                stop: None,
            },
            None,
            &|_| {},
        )
        .expect("renders")
        .0;
        // (The pilot takes light subpaths in a share of the samples, chosen for the whole
        // render: every part must draw the same ones.)
        let share = single.stats.light_paths.expect("bdpt");
        assert!(share > 0.0 && share < 1.0, "{rel}: share {share}");
        let single = single.film;
        let mut parts: Vec<_> = (0..count)
            .map(|i| {
                let plan = PartPlan {
                    index: i,
                    count,
                    plan_spp: spp as u64,
                    start_spp: 0,
                };
                let c = render_part(&job, &plan, SEED, None, hash).expect("part");
                (std::path::PathBuf::from(format!("part-{i}")), c)
            })
            .collect();
        parts.reverse();
        let merged = merge_parts(parts, None).expect("merges").film();
        assert_eq!(merged.samples, single.samples, "{rel}");
        assert!(
            merged.sum == single.sum && merged.sum_sq == single.sum_sq,
            "{rel}: sums"
        );
        assert!(merged.weight == single.weight, "{rel}: weights");
        assert!(single.sum.iter().any(|p| p[0] > 0.0), "{rel}: black");
    }
}

/// What bdpt cannot render is refused in one line (participating media), as are bad
/// strategy parameters; `--integrator bdpt` switches a path scene, taking its depths.
#[test]
fn bad_scenes_and_parameters_are_refused_in_one_line() {
    let base = |integrator: &str, extra: &str| {
        format!(
            r#"<scene version="3.0.0">
                {integrator}
                <sensor type="perspective">
                    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform></sensor>
                <shape type="sphere">{extra}</shape>
                <emitter type="point"><point name="position" x="0" y="3" z="0"/></emitter>
            </scene>"#
        )
    };
    let medium = r#"<bsdf type="null"/><medium type="homogeneous" name="interior">
        <rgb name="sigma_t" value="1"/><rgb name="albedo" value="0.5"/></medium>"#;
    let bdpt = |params: &str| format!(r#"<integrator type="bdpt">{params}</integrator>"#);
    for (xml, what) in [
        (base(&bdpt(""), medium), "media"),
        (
            base(&bdpt(r#"<integer name="strategy_s" value="1"/>"#), ""),
            "strategy_t",
        ),
        (
            base(
                &bdpt(
                    r#"<integer name="strategy_s" value="1"/><integer name="strategy_t" value="1"/>"#,
                ),
                "",
            ),
            "(1, 1)",
        ),
        (
            base(
                &bdpt(
                    r#"<integer name="max_depth" value="2"/><integer name="strategy_s" value="2"/><integer name="strategy_t" value="2"/>"#,
                ),
                "",
            ),
            "max_depth",
        ),
        (
            base(&bdpt(r#"<boolean name="strategy_mis" value="false"/>"#), ""),
            "strategy_mis",
        ),
        (
            base(&bdpt(r#"<integer name="rr_depth" value="0"/>"#), ""),
            "rr_depth",
        ),
    ] {
        let e = Job::from_xml_str(&xml, &repo_path("tests/inline.xml"), &[])
            .err()
            .unwrap_or_else(|| panic!("{what}: accepted"))
            .to_string();
        assert!(e.contains(what) && !e.contains('\n'), "{what}: {e}");
    }
    let path = base(
        r#"<integrator type="path"><integer name="max_depth" value="4"/><boolean name="hide_emitters" value="true"/></integrator>"#,
        "",
    );
    let mut desc =
        Scene::description_from_xml_str(&path, &repo_path("tests/inline.xml"), &[]).expect("loads");
    desc.use_integrator("bdpt").expect("bdpt");
    let job = Job::build(&desc).expect("builds");
    let Integrator::Bdpt(b) = &job.integrator else {
        panic!("not bdpt")
    };
    assert_eq!((b.max_depth, b.rr_depth, b.hide_emitters), (4, 5, true));
    assert_eq!((b.strategy, b.strategy_mis), (None, true));
}
