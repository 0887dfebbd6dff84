//! The particle tracer (`ptracer`) against answers known in closed form, and its guarantees
//! (determinism at any thread count, one-line errors). Mitsuba's own ptracer scene is in
//! tests/mitsuba_suite.rs; the path-traced Mitsuba references of the validation scenes in
//! tests/validation.rs (entries with `integrator = "ptracer"`).
//!
//! Per-pixel checks are z-tests with the film's per-pixel variance, Šidák-corrected α = 0.01
//! over all pixel-channels; image means are z-tested at α = 0.01 / (number of means).

mod common;
use common::*;
use glam::{Vec2, Vec3};
use penumbra::integrator::Integrator;
use penumbra::render::Job;
use penumbra::scene::Scene;
use penumbra::study::stats::{normal_critical_z, sidak};

const SEED: u64 = 0x97ace;

fn sensor(origin: &str, target: &str, up: &str, fov: f32, res: usize) -> String {
    format!(
        r#"<sensor type="perspective">
            <float name="fov" value="{fov}"/>
            <transform name="to_world"><lookat origin="{origin}" target="{target}" up="{up}"/></transform>
            <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
            <film type="hdrfilm"><integer name="width" value="{res}"/><integer name="height" value="{res}"/>
                <rfilter type="box"/></film>
        </sensor>"#
    )
}

/// z-tests every pixel-channel of `out` (rendered at `spp`) against `expected(pixel)`,
/// Šidák α = 0.01; returns the failures and the worst |z|.
fn pixel_z_test(
    out: &penumbra::render::RenderOutput,
    spp: u32,
    expected: impl Fn(usize) -> [f64; 3],
) -> (usize, f64) {
    let img = out.film.image();
    let var = out.film.sample_variance();
    let z_crit = normal_critical_z(sidak(0.01, img.len() * 3));
    let (mut fails, mut worst) = (0, 0.0f64);
    for (i, (p, v)) in img.iter().zip(&var).enumerate() {
        let e = expected(i);
        for c in 0..3 {
            // Floor the variance as Mitsuba's test does, for pixels with a single splat.
            let se = (v[c].max(1e-6) as f64 / spp as f64).sqrt();
            let z = (p[c] as f64 - e[c]).abs() / se;
            worst = worst.max(z);
            if z > z_crit {
                fails += 1;
            }
        }
    }
    (fails, worst)
}

/// A diffuse plane (reflectance 0.5) under a point light of intensity I, seen from above:
/// each pixel shows the average over its area of L = (ρ/π) I cos θ / r² at the plane point
/// seen (a 6 x 6 midpoint rule per pixel). Light tracing reaches
/// every pixel only through the connection of the first vertex to the camera, so this
/// checks W_e, the splat position, the BSDF in importance mode and the point light's rays.
#[test]
fn point_light_on_a_diffuse_plane_is_analytic() {
    // Light tracing lands ~λ splats in a pixel, λ ∝ particles per pixel: at 8 x 8 pixels and
    // 4096 spp λ ≈ 2000, so the per-pixel variance estimates are sound.
    let (res, spp) = (8usize, 4096u32);
    let (light, intensity, rho) = (Vec3::new(0.3, -0.2, 1.0), 5.0f64, 0.5f64);
    let xml = format!(
        r#"<scene version="3.0.0">
            <integrator type="ptracer"><integer name="max_depth" value="2"/></integrator>
            {}
            <shape type="rectangle">
                <transform name="to_world"><scale value="2"/></transform>
                <bsdf type="diffuse"><rgb name="reflectance" value="{rho}"/></bsdf>
            </shape>
            <emitter type="point">
                <point name="position" x="{}" y="{}" z="{}"/>
                <rgb name="intensity" value="{intensity}"/>
            </emitter>
        </scene>"#,
        sensor("0, 0, 2", "0, 0, 0", "0, 1, 0", 60.0, res),
        light.x,
        light.y,
        light.z
    );
    let scene = scene_from_str(&xml);
    assert!(matches!(scene.integrator, Integrator::ParticleTracer(_)));
    // penumbra renders in camera-relative coordinates (the camera at the origin): the
    // plane lies at z = −2 and the light at `light` − (0, 0, 2).
    let expected = |i: usize| {
        let (x, y) = (i % res, i / res);
        let n = 6;
        let mut sum = 0.0;
        for k in 0..n * n {
            let s = Vec2::new(
                (x as f32 + ((k % n) as f32 + 0.5) / n as f32) / res as f32,
                (y as f32 + ((k / n) as f32 + 0.5) / n as f32) / res as f32,
            );
            let ray = scene.scene.camera.generate_ray(s);
            let t = (-2.0 - ray.o.z) / ray.d.z;
            let p = ray.at(t).as_dvec3();
            let v = (light - Vec3::new(0.0, 0.0, 2.0)).as_dvec3() - p;
            let r2 = v.length_squared();
            sum += rho / std::f64::consts::PI * intensity * (v.z / r2.sqrt()) / r2;
        }
        [sum / (n * n) as f64; 3]
    };
    let out = render_scene(&scene, spp, SEED, None);
    let (fails, worst) = pixel_z_test(&out, spp, expected);
    assert_eq!(fails, 0, "worst |z| {worst}");
    // The image mean, to a few tenths of a percent.
    let (mean, se) = image_mean_and_se(&out, spp);
    let want: f64 = (0..res * res).map(|i| expected(i)[0]).sum::<f64>() / (res * res) as f64;
    let z_crit = normal_critical_z(0.01 / 3.0);
    for c in 0..3 {
        let z = (mean[c] - want).abs() / se[c];
        assert!(z < z_crit, "channel {c}: {} vs {want} (z = {z})", mean[c]);
        // Resolves a 2% error at 4 standard errors.
        assert!(
            se[c] < 5e-3 * want,
            "se {} too large to resolve a 2% error",
            se[c]
        );
    }
}

/// A closed diffuse sphere of radius 3 (reflectance ρ = 0.8) emitting L_e = 1 inwards, with
/// a point light of intensity I = 20 at its centre, the camera inside. The point light's
/// irradiance I/9 is uniform on the sphere, and so is every bounce, so every pixel shows
/// L = Σ_{j<k} ρ^j L_e + (ρ I / 9π) Σ_{j<k−1} ρ^j with max_depth k: 7.83 unbounded (Russian
/// roulette after 5 bounces carries ~40% of it), 3.459 at k = 3, 1 at k = 1 (the point
/// light cannot be seen). Every vertex of every light path is connected to the camera, so
/// this checks the depth count, the throughput update, Russian roulette's weight and the
/// choice among two emitters.
#[test]
fn furnace_sphere_sums_the_geometric_series() {
    let (rho, le, intensity) = (0.8f64, 1.0f64, 20.0f64);
    let direct = rho * intensity / (9.0 * std::f64::consts::PI);
    let series = |n: i64| (0..n.max(0)).map(|j| rho.powi(j as i32)).sum::<f64>();
    for (max_depth, want) in [
        (-1i64, (le + direct) / (1.0 - rho)),
        (3, le * series(3) + direct * series(2)),
        (1, le),
    ] {
        let xml = format!(
            r#"<scene version="3.0.0">
                <integrator type="ptracer"><integer name="max_depth" value="{max_depth}"/></integrator>
                {}
                <shape type="sphere">
                    <float name="radius" value="3"/>
                    <boolean name="flip_normals" value="true"/>
                    <bsdf type="diffuse"><rgb name="reflectance" value="{rho}"/></bsdf>
                    <emitter type="area"><rgb name="radiance" value="{le}"/></emitter>
                </shape>
                <emitter type="point"><rgb name="intensity" value="{intensity}"/></emitter>
            </scene>"#,
            sensor("0.5, 0.2, 0", "0, 0, 1", "0, 1, 0", 50.0, 16)
        );
        let scene = scene_from_str(&xml);
        let spp = 2048;
        let out = render_scene(&scene, spp, SEED, None);
        let (fails, worst) = pixel_z_test(&out, spp, |_| [want; 3]);
        assert_eq!(fails, 0, "max_depth {max_depth}: worst |z| {worst}");
        let (mean, se) = image_mean_and_se(&out, spp);
        let z_crit = normal_critical_z(0.01 / 9.0);
        for c in 0..3 {
            let z = (mean[c] - want).abs() / se[c];
            assert!(
                z < z_crit,
                "max_depth {max_depth}: {} vs {want} (z = {z})",
                mean[c]
            );
            // Resolves a 4% error at 4 standard errors.
            assert!(se[c] < 1e-2 * want, "se {}", se[c]);
        }
    }
}

/// What the camera sees directly (max_depth 1): an area light's radiance on its front,
/// nothing on its back or with `hide_emitters`, and a constant environment's radiance in
/// every other pixel.
#[test]
fn emitters_seen_directly() {
    let scene_xml = |extra: &str, hide: bool, flip: bool| {
        format!(
            r#"<scene version="3.0.0">
                <integrator type="ptracer">
                    <integer name="max_depth" value="1"/>
                    <boolean name="hide_emitters" value="{hide}"/>
                </integrator>
                {}
                <shape type="rectangle">
                    <boolean name="flip_normals" value="{flip}"/>
                    <emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter>
                </shape>
                {extra}
            </scene>"#,
            sensor("0, 0, 2.2", "0, 0, 0", "0, 1, 0", 60.0, 16)
        )
    };
    // A constant environment is seen through directions drawn uniformly on the sphere, ~8%
    // of which fall in this image: 4096 spp lands ~150 of them in each pixel.
    let spp = 4096;
    // The rectangle [-1, 1]² at z = 0 seen from z = 2.2 (fov 60): covers the pixels whose
    // centre ray meets it (edge pixels, partly covered, are left out).
    let scene = scene_from_str(&scene_xml("", false, false));
    let coverage = |i: usize| {
        let s = Vec2::new(
            ((i % 16) as f32 + 0.5) / 16.0,
            ((i / 16) as f32 + 0.5) / 16.0,
        );
        let r = scene.scene.camera.generate_ray(s);
        // camera-relative coordinates: the rectangle lies at z = −2.2
        let p = r.at((-2.2 - r.o.z) / r.d.z);
        let m = p.x.abs().max(p.y.abs());
        if m < 0.93 {
            Some(true)
        } else if m > 1.07 {
            Some(false)
        } else {
            None
        }
    };
    let check = |scene: &Job, inside: [f64; 3], outside: [f64; 3]| {
        let out = render_scene(scene, spp, SEED, None);
        let img = out.film.image();
        let (mut fails, mut worst) = (0, 0.0f64);
        let var = out.film.sample_variance();
        let z_crit = normal_critical_z(sidak(0.01, img.len() * 3));
        for i in 0..img.len() {
            let want = match coverage(i) {
                Some(true) => inside,
                Some(false) => outside,
                None => continue,
            };
            for c in 0..3 {
                let d = (img[i][c] as f64 - want[c]).abs();
                if want[c] == 0.0 {
                    assert_eq!(img[i][c], 0.0, "pixel {i} should be black");
                    continue;
                }
                let z = d / (var[i][c].max(1e-6) as f64 / spp as f64).sqrt();
                worst = worst.max(z);
                fails += usize::from(z > z_crit);
            }
        }
        assert_eq!(fails, 0, "worst |z| {worst}");
    };
    check(&scene, [3.0, 2.0, 1.0], [0.0; 3]);
    check(
        &scene_from_str(&scene_xml("", true, false)),
        [0.0; 3],
        [0.0; 3],
    );
    check(
        &scene_from_str(&scene_xml("", false, true)),
        [0.0; 3],
        [0.0; 3],
    );
    let env = r#"<emitter type="constant"><rgb name="radiance" value="0.5, 0.7, 0.9"/></emitter>"#;
    check(
        &scene_from_str(&scene_xml(env, false, false)),
        [3.0, 2.0, 1.0],
        [0.5, 0.7, 0.9],
    );
    // max_depth 0: black.
    let mut s = scene_from_str(&scene_xml(env, false, false));
    if let Integrator::ParticleTracer(p) = &mut s.integrator {
        p.max_depth = 0;
    }
    let out = render_scene(&s, 4, SEED, None);
    assert!(out.film.image().iter().all(|p| *p == [0.0; 3]));
}

/// The same seed gives the same image bit for bit with 1 and 2 threads, and another seed
/// another image; the sample count and variance mean what they mean for camera
/// integrators (one pass of width × height particles is one sample per pixel).
#[test]
fn deterministic_at_any_thread_count() {
    let scene = load(
        "validation/mitsuba-suite/tests/scenes/various_emitters/test_various_emitters_ptracer.xml",
        &[("resx", "64"), ("resy", "16")],
    );
    let a = render_scene(&scene, 8, SEED, Some(1));
    let b = render_scene(&scene, 8, SEED, Some(2));
    let c = render_scene(&scene, 8, SEED + 1, Some(2));
    assert_eq!(a.film.sum, b.film.sum);
    assert_eq!(a.film.sum_sq, b.film.sum_sq);
    assert_ne!(a.film.sum, c.film.sum);
    assert_eq!(a.film.spp(), 8.0);
    assert_eq!(a.stats.paths, 64 * 16 * 8);
    assert!(a.stats.path.rays > a.stats.paths);
    // Rendering 8 spp as 3 + 5 (continuing the sample indices) adds up to the same sums.
    let first = scene
        .render(
            &penumbra::render::RenderSettings {
                spp: 3,
                first_sample: 0,
                seed: SEED,
                threads: None,
                sampler: None,
            },
            &|_, _| {},
        )
        .unwrap();
    let second = scene
        .render(
            &penumbra::render::RenderSettings {
                spp: 5,
                first_sample: 3,
                seed: SEED,
                threads: None,
                sampler: None,
            },
            &|_, _| {},
        )
        .unwrap();
    let mut sum = first.film.clone();
    sum.add(&second.film);
    assert_eq!(sum.spp(), 8.0);
    for (x, y) in sum.sum.iter().zip(&a.film.sum) {
        for k in 0..3 {
            assert!(
                (x[k] - y[k]).abs() <= 1e-12 * y[k].abs().max(1.0),
                "{x:?} vs {y:?}"
            );
        }
    }
}

/// What light tracing cannot do is refused with one line: a thin lens or orthographic
/// camera, participating media, an unknown integrator name.
#[test]
fn unsupported_scenes_are_refused_in_one_line() {
    let base = |sensor_xml: &str, extra: &str| {
        format!(
            r#"<scene version="3.0.0">
                <integrator type="ptracer"/>
                {sensor_xml}
                <shape type="sphere">{extra}</shape>
                <emitter type="point"><point name="position" x="0" y="3" z="0"/></emitter>
            </scene>"#
        )
    };
    let thinlens = r#"<sensor type="thinlens"><float name="aperture_radius" value="0.1"/>
        <float name="focus_distance" value="3"/>
        <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform></sensor>"#;
    let ortho = r#"<sensor type="orthographic">
        <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform></sensor>"#;
    let pinhole = r#"<sensor type="perspective">
        <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform></sensor>"#;
    let medium = r#"<bsdf type="null"/><medium type="homogeneous" name="interior">
        <rgb name="sigma_t" value="1"/><rgb name="albedo" value="0.5"/></medium>"#;
    for (xml, what) in [
        (base(thinlens, ""), "pinhole"),
        (base(ortho, ""), "pinhole"),
        (base(pinhole, medium), "media"),
    ] {
        let e = Job::from_xml_str(&xml, &repo_path("tests/inline.xml"), &[])
            .err()
            .unwrap_or_else(|| panic!("{what}: accepted"))
            .to_string();
        assert!(e.contains(what) && !e.contains('\n'), "{e}");
    }
    let bad = base(pinhole, "").replace(
        r#"<integrator type="ptracer"/>"#,
        r#"<integrator type="ptracer"><integer name="max_depth" value="-2"/></integrator>"#,
    );
    let e = Job::from_xml_str(&bad, &repo_path("tests/inline.xml"), &[])
        .err()
        .expect("max_depth -2 accepted")
        .to_string();
    assert!(e.contains("max_depth") && !e.contains('\n'), "{e}");
    let mut desc =
        Scene::description_from_xml_str(&base(pinhole, ""), &repo_path("tests/inline.xml"), &[])
            .expect("description");
    let e = desc.use_integrator("bdpt").unwrap_err().to_string();
    assert!(e.contains("bdpt") && !e.contains('\n'), "{e}");
    desc.use_integrator("ptracer").expect("ptracer");
    let s = Job::build(&desc).expect("builds");
    assert!(matches!(s.integrator, Integrator::ParticleTracer(_)));
}

/// A light tracer under a constant sky of `radiance`, nothing else in the scene, seen by a
/// 60° pinhole of 4 × 4 pixels.
fn sky_only(radiance: f32) -> Job {
    scene_from_str(&format!(
        r#"<scene version="3.0.0">
            <integrator type="ptracer"/>
            {}
            <emitter type="constant"><rgb name="radiance" value="{radiance}"/></emitter>
        </scene>"#,
        sensor("0, 0, 2", "0, 0, 0", "0, 1, 0", 60.0, 4)
    ))
}

/// A connection whose value is zero is not worth a shadow ray: with a black environment (the
/// only emitter, nothing else in the scene) the light tracer renders black without tracing a
/// single ray, and splats no NaN.
#[test]
fn a_black_environment_traces_no_rays() {
    let out = render_scene(&sky_only(0.0), 16, SEED, None);
    assert_eq!(out.stats.paths, 4 * 4 * 16);
    assert_eq!(out.stats.path.rays, 0);
    assert_eq!(out.stats.nonfinite, 0);
    assert!(out.film.image().iter().all(|p| *p == [0.0; 3]));
}

/// The same scene with a sky of radiance 1: each particle traces one light-path ray (which
/// escapes) and, when the sky direction it draws from the pinhole (uniform over the sphere
/// for a constant sky) falls inside the camera's frustum, one ray to test that connection.
/// The frustum of a 60° × 60° pinhole subtends Ω = 4 asin(sin² 30°) sr, so the rays beyond
/// one per particle are Binomial(n, Ω / 4π): z-test at α = 0.01.
#[test]
fn a_sky_seen_from_the_camera_costs_one_ray_per_connection() {
    let out = render_scene(&sky_only(1.0), 256, SEED, None);
    let n = out.stats.paths as f64;
    assert_eq!(n, 4.0 * 4.0 * 256.0);
    let half = 30f64.to_radians();
    let p = 4.0 * (half.sin() * half.sin()).asin() / (4.0 * std::f64::consts::PI);
    let connections = out.stats.path.rays as f64 - n;
    let z = (connections - n * p) / (n * p * (1.0 - p)).sqrt();
    assert!(
        z.abs() < 2.576,
        "{connections} connection rays, expected {:.1} (z = {z:.2})",
        n * p
    );
}

/// Russian roulette's survival probability, q = min(max(β) η², 0.95) (Mitsuba's
/// `ptracer.cpp`), counted: a point light of power W = 4π I = 1.2 at the centre of a glass
/// sphere (n = 1.5, radius 1) inside a closed diffuse sphere, max_depth 3 and rr_depth 1, so
/// that every light path meets exactly one roulette decision, right after the glass. Its rays
/// meet the glass at normal incidence: reflected with probability R = ((n − 1)/(n + 1))²
/// (η stays 1, β = W: q = 0.95), else transmitted out of the glass (η = 1/n, β = W in
/// importance mode: q = W/n² = 0.533). The paths ended by roulette are Binomial(N, p) with
/// p = R · 0.05 + (1 − R)(1 − W/n²) = 0.450; z-test at α = 0.01. Dropping η² from q (q =
/// β η/η) or adding instead of multiplying (q = β η + η) makes q = 0.95 on both branches
/// (p = 0.05): a change of variance and ray count that no image mean sees.
#[test]
fn roulette_survival_follows_throughput_and_eta_squared() {
    let (n_glass, power) = (1.5f64, 1.2f64);
    let intensity = power / (4.0 * std::f64::consts::PI);
    let xml = format!(
        r#"<scene version="3.0.0">
            <integrator type="ptracer">
                <integer name="max_depth" value="3"/>
                <integer name="rr_depth" value="1"/>
            </integrator>
            {}
            <shape type="sphere">
                <float name="radius" value="1"/>
                <bsdf type="dielectric">
                    <float name="int_ior" value="{n_glass}"/>
                    <float name="ext_ior" value="1"/>
                </bsdf>
            </shape>
            <shape type="sphere">
                <float name="radius" value="3"/>
                <boolean name="flip_normals" value="true"/>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
            </shape>
            <emitter type="point"><rgb name="intensity" value="{intensity}"/></emitter>
        </scene>"#,
        sensor("0, 2, 0", "0, 2, 1", "0, 1, 0", 50.0, 4)
    );
    let scene = scene_from_str(&xml);
    let out = render_scene(&scene, 1024, SEED, None);
    let n = out.stats.paths;
    assert_eq!(n, 4 * 4 * 1024);
    assert_eq!(out.stats.nonfinite, 0);
    let r = ((n_glass - 1.0) / (n_glass + 1.0)).powi(2);
    let p = r * (1.0 - 0.95) + (1.0 - r) * (1.0 - power / (n_glass * n_glass));
    let ended = out.stats.path.rr_terminated as f64;
    let nf = n as f64;
    let z = (ended - nf * p) / (nf * p * (1.0 - p)).sqrt();
    eprintln!(
        "{ended} of {n} paths ended by roulette, expected {:.1} (z = {z:.2})",
        nf * p
    );
    assert!(
        z.abs() < normal_critical_z(0.01),
        "{ended} of {n} paths ended by roulette, expected {:.1} (z = {z:.2})",
        nf * p
    );
    // Every path meets the glass; every survivor meets a second surface (the spheres are
    // closed) and ends there at max_depth.
    assert_eq!(out.stats.path.bounces, 2 * n - out.stats.path.rr_terminated);
}
