//! Emitter sampling through the scene (power-proportional selection included): chi-square
//! tests of the sampled directions against the density that the path tracer's MIS uses
//! (`Scene::pdf_emitter_direction` for surfaces, `Scene::pdf_environment` for escaping rays),
//! sample/pdf/eval consistency, analytic irradiance, and the delta lights' values.

mod common;
use common::*;
use glam::{Vec2, Vec3};
use penumbra::emitter::Emitter;
use penumbra::geometry::{Frame, Ray};
use penumbra::math::simpson;
use penumbra::render::Job;
use penumbra::sampler::SampleStream;
use penumbra::scene::Scene;
use penumbra::shape::SurfaceInteraction;
use penumbra::spectrum::Spectrum;
use penumbra::study::chi2::{chi2_test, Chi2Config};
use penumbra::study::stats::{normal_critical_z, sidak};
use std::f64::consts::PI;

/// Chi-square tests in this file (for the Šidák correction of α = 0.01).
const CHI2_TESTS: usize = 15;

fn scene(body: &str) -> Job {
    scene_from_str(&format!(
        r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
    {body}
</scene>"#
    ))
}

fn reference_point(p: Vec3, n: Vec3) -> SurfaceInteraction {
    SurfaceInteraction {
        p,
        p_error: Vec3::ZERO,
        t: 1.0,
        ng: n,
        frame: Frame::from_normal(n),
        uv: Vec2::ZERO,
        dp_du: Vec3::ZERO,
        dp_dv: Vec3::ZERO,
        shape: 0,
        prim: 0,
        bary: Vec2::ZERO,
    }
}

/// The density the path tracer's MIS uses for direction `d` from `p`, and the radiance it
/// sees there: the emitter surface hit first, or the environment.
fn pdf_and_radiance(scene: &Job, p: Vec3, d: Vec3) -> (f64, Spectrum) {
    match scene.scene.intersect(&Ray::new(p, d, f32::INFINITY)) {
        Some(hit) => {
            let le = match scene.scene.shapes[hit.shape as usize].emitter {
                Some(e) => match &scene.scene.emitters[e as usize] {
                    Emitter::Area(a) => a.eval(
                        &hit,
                        -d,
                        &scene.scene.shapes,
                        penumbra::spectrum::NO_WAVELENGTHS,
                    ),
                    _ => Spectrum::ZERO,
                },
                None => Spectrum::ZERO,
            };
            (scene.scene.pdf_emitter_direction(p, &hit) as f64, le)
        }
        None => (
            scene.scene.pdf_environment(d) as f64,
            scene
                .scene
                .eval_environment(d, penumbra::spectrum::NO_WAVELENGTHS),
        ),
    }
}

/// Chi-square test of `scene.sample_emitter_direction` from `p` (delta samples left out),
/// plus the per-sample consistency of pdf and radiance with what a ray in that direction
/// finds.
fn check_sampling(name: &str, scene: &Job, p: Vec3, seed: u64) {
    let si = reference_point(p, Vec3::Z);
    let n = 300_000;
    // Emitter densities jump at the silhouettes of the lights: a finer Simpson rule than
    // for smooth BSDF densities keeps the cells they cut accurate (with 8 sub-intervals the
    // rectangle's χ² was 1818 on 90 dof, with 32 it is 100).
    let cfg = Chi2Config {
        quadrature: 96,
        ..Chi2Config::default()
    };
    let mut checked = 0;
    let mut at_edges = 0;
    let r = chi2_test(
        n,
        |i| {
            let u = SampleStream::new(seed, i as u64, 0).next_2d();
            let ds =
                scene
                    .scene
                    .sample_emitter_direction(&si, u, penumbra::spectrum::NO_WAVELENGTHS)?;
            // Delta samples have no density; occluded samples (behind another emitter)
            // contribute nothing, and the density of the rest at d is that of the emitter
            // a ray along d finds first.
            if ds.delta || scene.scene.occluded(&Scene::shadow_ray(&si, &ds)) {
                return None;
            }
            // Per-sample checks away from grazing emitter points: there the f32 ray along
            // ds.d re-hits a curved emitter up to ~1e-4 from the sampled point, where 1/cos
            // (in every area-to-solid-angle density) differs by more than the tolerance.
            let grazing = ds.n != Vec3::ZERO && ds.n.dot(ds.d).abs() < 0.05;
            if !grazing {
                let (pdf, le) = pdf_and_radiance(scene, p, ds.d);
                let same = |a: f64, b: f64| (a - b).abs() <= 2e-3 * a.max(b);
                if !same(pdf, ds.pdf as f64) {
                    // Densities jump at pixel edges (environment maps) and at the edges of
                    // a light (the ray along an f32 direction to a sampled point on the edge
                    // may miss it). Accepted only there: pdf() must take the sampled value
                    // within 1e-5 rad of d.
                    let f = Frame::from_normal(ds.d);
                    let near: Vec<f64> = [f.s, -f.s, f.t, -f.t]
                        .iter()
                        .map(|&o| pdf_and_radiance(scene, p, (ds.d + 1e-5 * o).normalize()).0)
                        .collect();
                    assert!(
                        near.iter().any(|&q| same(q, ds.pdf as f64)),
                        "{name}: sampled pdf {} vs pdf() {pdf} at {} (around it: {near:?})",
                        ds.pdf,
                        ds.d
                    );
                    at_edges += 1;
                } else {
                    assert!(
                        (le - ds.radiance).abs().max_element() <= 1e-3 * le.max_element().max(1e-3),
                        "{name}: sampled radiance {} vs eval {le}",
                        ds.radiance
                    );
                }
                checked += 1;
            }
            Some(ds.d)
        },
        |d| pdf_and_radiance(scene, p, d).0,
        &cfg,
    );
    let alpha = sidak(0.01, CHI2_TESTS);
    eprintln!(
        "{name}: chi2 {:.1}, dof {}, p = {:.4}, pdf integral {:.4}, landed {}",
        r.statistic, r.dof, r.p_value, r.pdf_integral, r.landed
    );
    assert!(checked > n / 10, "{name}: only {checked} samples checked");
    // edge samples are a set of measure ~ (1e-6 rad / pixel or light size): a handful
    assert!(
        at_edges * 1000 < checked,
        "{name}: {at_edges} of {checked} samples at density edges"
    );
    assert!(r.p_value > alpha, "{name}: {r:?}");
    // The pdf integrates to the fraction of samples that landed (not occluded, not delta):
    // within 5 binomial standard errors plus the quadrature's 2e-3, so that a 1% pdf scale
    // error fails.
    let frac = r.landed as f64 / n as f64;
    let se = (frac * (1.0 - frac) / n as f64).sqrt();
    assert!(
        (r.pdf_integral - frac).abs() < 5.0 * se + 2e-3,
        "{name}: pdf integral {} vs fraction landed {}",
        r.pdf_integral,
        r.landed as f64 / n as f64
    );
}

#[test]
fn area_lights_on_every_shape_chi2() {
    let s = scene(
        r#"<shape type="rectangle">
        <transform name="to_world"><scale value="0.5, 0.3, 1"/><rotate value="1, 0, 0" angle="120"/><translate value="0, 1, 0.5"/></transform>
        <emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>
    </shape>"#,
    );
    check_sampling("rectangle", &s, Vec3::new(0.2, -0.3, 0.1), 1);
    let s = scene(
        r#"<shape type="disk">
        <transform name="to_world"><scale value="0.4"/><rotate value="0, 1, 0" angle="-70"/><translate value="1.2, 0.1, 0"/></transform>
        <emitter type="area"><float name="radiance" value="5"/></emitter>
    </shape>"#,
    );
    check_sampling("disk", &s, Vec3::new(0.0, 0.2, 0.4), 2);
    let s = scene(
        r#"<shape type="cube">
        <transform name="to_world"><scale value="0.3, 0.2, 0.4"/><rotate value="1, 1, 0" angle="30"/><translate value="0, 0, 1.5"/></transform>
        <emitter type="area"><float name="radiance" value="1"/></emitter>
    </shape>"#,
    );
    check_sampling("cube", &s, Vec3::new(0.5, -0.5, 0.0), 3);
}

#[test]
fn area_light_on_an_obj_mesh_chi2() {
    // A tetrahedron (convex: every face that faces the reference point is visible).
    let dir = std::env::temp_dir().join(format!("penumbra-emitters-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("tet.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let s = scene(&format!(
        r#"<shape type="obj">
        <string name="filename" value="{}"/>
        <boolean name="face_normals" value="true"/>
        <transform name="to_world"><translate value="-0.2, -0.3, 1.2"/></transform>
        <emitter type="area"><float name="radiance" value="1"/></emitter>
    </shape>"#,
        obj.display()
    ));
    check_sampling("obj tetrahedron", &s, Vec3::new(0.4, 0.6, -0.3), 4);
    std::fs::remove_dir_all(&dir).ok();
}

/// Writes `rim.png` into `dir`: 12x7 texels, black in the first column and in the first and
/// last rows (see [`textured_area_lights_chi2`]).
fn write_rim_texture(dir: &std::path::Path) -> std::path::PathBuf {
    let rim = dir.join("rim.png");
    image::RgbImage::from_fn(12, 7, |x, y| {
        if x == 0 || y == 0 || y == 6 {
            image::Rgb([0, 0, 0])
        } else {
            image::Rgb([(20 * x) as u8, (30 * y) as u8, 200])
        }
    })
    .save(&rim)
    .unwrap();
    rim
}

fn bitmap_radiance(file: &str, filter: &str, wrap: &str, rim: &std::path::Path) -> String {
    let path = if file == "rim.png" {
        rim.to_path_buf()
    } else {
        repo_path(&format!("validation/mitsuba-suite/common/textures/{file}"))
    };
    format!(
        r#"<texture type="bitmap" name="radiance"><string name="filename" value="{}"/><string name="filter_type" value="{filter}"/><string name="wrap_mode" value="{wrap}"/></texture>"#,
        path.display()
    )
}

/// Textured radiance, sampled as Mitsuba does (uv in proportion to the texels, mapped onto
/// the shape), on flat emitters: a rectangle, a UV-mapped OBJ mesh and a disk, with each
/// filter and wrap mode, and a checkerboard (sampled uniformly in uv). The per-sample checks
/// compare the sampled radiance with the texture looked up where a ray in that direction
/// hits.
///
/// The disk's parameterisation makes the area density infinite at its centre (u = 0, where
/// |∂p/∂u × ∂p/∂v| vanishes), an integrable singularity the chi-square's cell quadrature
/// cannot integrate: its texture (`rim.png`) is black in the first column, so the density is
/// 0 there. Curved emitters are tested in [`textured_curved_lights_irradiance`]: their
/// solid-angle density is infinite along the silhouette.
#[test]
fn textured_area_lights_chi2() {
    let dir = std::env::temp_dir().join(format!("penumbra-textured-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let rim = write_rim_texture(&dir);
    let bitmap = |file: &str, filter: &str, wrap: &str| bitmap_radiance(file, filter, wrap, &rim);
    let cases = [
        (
            "textured rectangle",
            format!(
                r#"<shape type="rectangle">
        <transform name="to_world"><scale value="0.5, 0.3, 1"/><rotate value="1, 0, 0" angle="160"/><translate value="0, 0.4, 0.8"/></transform>
        <emitter type="area">{}</emitter></shape>"#,
                bitmap("carrot.png", "bilinear", "repeat")
            ),
            Vec3::new(0.1, -0.2, 0.0),
        ),
        (
            "textured obj mesh",
            format!(
                r#"<shape type="obj"><string name="filename" value="{}"/>
        <transform name="to_world"><scale value="0.6"/><rotate value="1, 0, 0" angle="180"/><translate value="0.2, 0, 1"/></transform>
        <emitter type="area">{}</emitter></shape>"#,
                repo_path("validation/mitsuba-suite/common/meshes/rectangle.obj").display(),
                bitmap("flower.bmp", "nearest", "repeat")
            ),
            Vec3::new(0.0, 0.1, 0.0),
        ),
        (
            "textured disk",
            format!(
                r#"<shape type="disk"><transform name="to_world"><scale value="0.4"/><rotate value="0, 1, 0" angle="160"/><translate value="0.2, 0.1, 0.9"/></transform>
        <emitter type="area">{}</emitter></shape>"#,
                bitmap("rim.png", "nearest", "clamp")
            ),
            Vec3::new(0.0, 0.2, 0.0),
        ),
        (
            "checkerboard rectangle",
            r#"<shape type="rectangle">
        <transform name="to_world"><scale value="0.5"/><rotate value="1, 0, 0" angle="180"/><translate value="0, 0, 1"/></transform>
        <emitter type="area"><texture type="checkerboard" name="radiance"><rgb name="color0" value="1, 2, 3"/><rgb name="color1" value="0.1"/></texture></emitter></shape>"#
                .to_string(),
            Vec3::new(0.3, 0.1, 0.0),
        ),
    ];
    for (i, (name, xml, p)) in cases.iter().enumerate() {
        check_sampling(name, &scene(xml), *p, 20 + i as u64);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Textured radiance on curved emitters (sphere, cylinder), sampled as Mitsuba does: the
/// next-event estimate of the irradiance at a point agrees with an independent estimate by
/// cosine-weighted hemisphere sampling and ray casting (E = π · mean L), z-test with Šidák
/// correction over the cases. A wrong Jacobian |∂p/∂u × ∂p/∂v|, solid-angle conversion or
/// uv mapping biases the first estimate.
#[test]
fn textured_curved_lights_irradiance() {
    let dir = std::env::temp_dir().join(format!("penumbra-curved-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let rim = write_rim_texture(&dir);
    let bitmap = |file: &str, filter: &str, wrap: &str| bitmap_radiance(file, filter, wrap, &rim);
    let cases = [
        (
            "textured sphere",
            format!(
                r#"<shape type="sphere"><point name="center" x="0.3" y="0.2" z="1.0"/><float name="radius" value="0.4"/>
        <emitter type="area">{}</emitter></shape>"#,
                bitmap("flower.bmp", "bilinear", "mirror")
            ),
        ),
        (
            "textured rotated sphere",
            format!(
                r#"<shape type="sphere"><transform name="to_world"><scale value="0.5"/><rotate value="0.6, 0.8, 0" angle="50"/><translate value="-0.2, 0.1, 1.1"/></transform>
        <emitter type="area">{}</emitter></shape>"#,
                bitmap("carrot.png", "nearest", "repeat")
            ),
        ),
        (
            "textured cylinder",
            format!(
                r#"<shape type="cylinder"><float name="radius" value="0.3"/><point name="p0" x="-0.5" y="0" z="1"/><point name="p1" x="0.5" y="0.2" z="1.1"/>
        <emitter type="area">{}</emitter></shape>"#,
                bitmap("rim.png", "bilinear", "clamp")
            ),
        ),
    ];
    let z_crit = normal_critical_z(sidak(0.01, cases.len()));
    let si = reference_point(Vec3::ZERO, Vec3::Z);
    let n = 400_000;
    for (i, (name, xml)) in cases.iter().enumerate() {
        let s = scene(xml);
        let nee = nee_irradiance(&s, &si, n, 40 + i as u64);
        let (mut s1, mut s2) = (0.0, 0.0);
        for k in 0..n {
            let u = SampleStream::new(50 + i as u64, k as u64, 0).next_2d();
            let d = penumbra::sampling::square_to_cosine_hemisphere(u);
            let (_, le) = pdf_and_radiance(&s, si.p, d);
            let v = PI * le.x as f64;
            s1 += v;
            s2 += v * v;
        }
        let m = s1 / n as f64;
        let se = ((s2 / n as f64 - m * m) / n as f64).sqrt();
        let z = (nee.0 - m) / (nee.1 * nee.1 + se * se).sqrt();
        eprintln!(
            "{name}: NEE {:.7} ± {:.5}, cosine sampling {m:.7} ± {se:.5}, z = {z:.3}",
            nee.0, nee.1
        );
        assert!(m > 0.0, "{name}: the emitter is not seen");
        assert!(z.abs() < z_crit, "{name}: z = {z} (critical {z_crit})");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sphere_lights_from_outside_and_inside_chi2() {
    let s = scene(
        r#"<shape type="sphere">
        <point name="center" x="0.3" y="0.2" z="1.0"/><float name="radius" value="0.4"/>
        <emitter type="area"><float name="radiance" value="2"/></emitter>
    </shape>"#,
    );
    // Outside, near and far: cone sampling.
    check_sampling("sphere outside near", &s, Vec3::new(0.0, 0.0, 0.3), 5);
    check_sampling("sphere outside far", &s, Vec3::new(-3.0, 2.0, -4.0), 6);
    // Inside a sphere that emits inwards: area sampling.
    let s = scene(
        r#"<shape type="sphere">
        <float name="radius" value="2"/><boolean name="flip_normals" value="true"/>
        <emitter type="area"><float name="radiance" value="2"/></emitter>
    </shape>"#,
    );
    check_sampling("sphere inside", &s, Vec3::new(0.5, -0.7, 0.9), 7);
}

#[test]
fn environment_lights_chi2() {
    let s =
        scene(r#"<emitter type="constant"><rgb name="radiance" value="0.2, 0.5, 1"/></emitter>"#);
    check_sampling("constant", &s, Vec3::ZERO, 8);
    let s = scene(
        r#"<emitter type="envmap">
        <string name="filename" value="../scenes/textures/sky-64x32.exr"/>
        <float name="scale" value="2"/>
        <transform name="to_world"><rotate value="0.70710678, 0.70710678, 0" angle="40"/></transform>
    </emitter>"#,
    );
    check_sampling("envmap", &s, Vec3::new(1.0, 2.0, 3.0), 9);
}

#[test]
fn several_lights_selected_uniformly_chi2() {
    // Rectangle, sphere, spot (delta: left out of the histogram) and an environment.
    let s = scene(
        r#"<shape type="rectangle">
        <transform name="to_world"><scale value="0.5"/><rotate value="1, 0, 0" angle="90"/><translate value="0, 1, 0"/></transform>
        <emitter type="area"><float name="radiance" value="3"/></emitter>
    </shape>
    <shape type="sphere">
        <point name="center" x="1" y="0" z="0"/><float name="radius" value="0.2"/>
        <emitter type="area"><float name="radiance" value="10"/></emitter>
    </shape>
    <emitter type="spot"><rgb name="intensity" value="2"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.05"/></emitter>"#,
    );
    // Uniform selection, as Mitsuba's Scene::sample_emitter does.
    for i in 0..4 {
        assert_eq!(s.scene.emitter_pmf(i), 0.25);
    }
    check_sampling(
        "rectangle + sphere + spot + constant",
        &s,
        Vec3::new(0.1, 0.0, 0.5),
        10,
    );
}

/// Mitsuba's `sampling_weight`: emitters are chosen in proportion to their weights as soon
/// as one is not 1, and the densities of the samples (and of the directions a BSDF sample
/// finds) include that probability.
#[test]
fn sampling_weights_choose_the_emitters_chi2() {
    let s = scene(
        r#"<shape type="rectangle">
        <transform name="to_world"><scale value="0.5"/><rotate value="1, 0, 0" angle="90"/><translate value="0, 1, 0"/></transform>
        <emitter type="area"><float name="radiance" value="3"/><float name="sampling_weight" value="3"/></emitter>
    </shape>
    <shape type="sphere">
        <point name="center" x="1" y="0" z="0"/><float name="radius" value="0.2"/>
        <emitter type="area"><float name="radiance" value="10"/><float name="sampling_weight" value="0.5"/></emitter>
    </shape>
    <emitter type="spot"><rgb name="intensity" value="2"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.05"/><float name="sampling_weight" value="2"/></emitter>"#,
    );
    for (i, w) in [3.0, 0.5, 1.0, 2.0].iter().enumerate() {
        assert!(
            (s.scene.emitter_pmf(i) - w / 6.5).abs() < 1e-7,
            "{i}: {}",
            s.scene.emitter_pmf(i)
        );
    }
    // The choices follow the weights: a z-test per emitter over 10^5 picks.
    let n = 100_000;
    let mut counts = [0usize; 4];
    for i in 0..n {
        let u = SampleStream::new(12, i as u64, 0).next_1d();
        counts[s.scene.pick_emitter(u).unwrap().0] += 1;
    }
    for (i, c) in counts.iter().enumerate() {
        let p = s.scene.emitter_pmf(i) as f64;
        let z = (*c as f64 - n as f64 * p) / (n as f64 * p * (1.0 - p)).sqrt();
        assert!(z.abs() < 4.0, "emitter {i}: {c} picks, z = {z:.2}");
    }
    check_sampling(
        "weighted rectangle + sphere + spot + constant",
        &s,
        Vec3::new(0.1, 0.0, 0.5),
        11,
    );
    // All weights 1 again: uniform, as without the parameter.
    let u = scene(
        r#"<emitter type="spot"><float name="sampling_weight" value="1"/></emitter>
    <emitter type="point"/>"#,
    );
    assert!(u.scene.emitter_weights.is_none());
}

/// The NEE estimate of the irradiance at `si` (normal `si.frame.n`), unoccluded, with its
/// standard error.
fn nee_irradiance(scene: &Job, si: &SurfaceInteraction, n: usize, seed: u64) -> (f64, f64) {
    let (mut s1, mut s2) = (0.0, 0.0);
    for i in 0..n {
        let u = SampleStream::new(seed, i as u64, 0).next_2d();
        let v =
            match scene
                .scene
                .sample_emitter_direction(si, u, penumbra::spectrum::NO_WAVELENGTHS)
            {
                Some(ds) => {
                    let cos = ds.d.dot(si.frame.n).max(0.0) as f64;
                    ds.radiance.x as f64 * cos / ds.pdf as f64
                }
                None => 0.0,
            };
        s1 += v;
        s2 += v * v;
    }
    let m = s1 / n as f64;
    (m, ((s2 / n as f64 - m * m) / n as f64).sqrt())
}

fn assert_irradiance(name: &str, est: (f64, f64), exact: f64) {
    eprintln!("{name}: E = {:.6} ± {:.6}, exact {exact:.6}", est.0, est.1);
    assert!(
        (est.0 - exact).abs() < 4.0 * est.1 && (est.0 - exact).abs() < 0.01 * exact,
        "{name}: {} ± {} vs {exact}",
        est.0,
        est.1
    );
}

#[test]
fn analytic_irradiance_from_disk_sphere_and_constant_environment() {
    // Disk of radius R at height h facing down: E = π L R² / (R² + h²) on its axis.
    let s = scene(
        r#"<shape type="disk">
        <transform name="to_world"><scale value="0.5"/><rotate value="1, 0, 0" angle="180"/><translate value="0, 0, 1"/></transform>
        <emitter type="area"><float name="radiance" value="2"/></emitter>
    </shape>"#,
    );
    let si = reference_point(Vec3::ZERO, Vec3::Z);
    assert_irradiance(
        "disk",
        nee_irradiance(&s, &si, 200_000, 11),
        PI * 2.0 * 0.25 / 1.25,
    );
    // Sphere of radius r at distance d, facing its centre: E = π L (r / d)².
    let s = scene(
        r#"<shape type="sphere">
        <point name="center" x="0" y="0" z="3"/><float name="radius" value="0.5"/>
        <emitter type="area"><float name="radiance" value="4"/></emitter>
    </shape>"#,
    );
    assert_irradiance(
        "sphere",
        nee_irradiance(&s, &si, 200_000, 12),
        PI * 4.0 / 36.0,
    );
    // Constant environment on an unoccluded plane: E = π L.
    let s = scene(r#"<emitter type="constant"><float name="radiance" value="0.7"/></emitter>"#);
    assert_irradiance("constant", nee_irradiance(&s, &si, 200_000, 13), PI * 0.7);
    // The envmap's irradiance on a horizontal plane against a brute-force quadrature of its
    // radiance over the upper hemisphere (midpoint rule on a fine (cos θ, φ) grid).
    let s = scene(
        r#"<emitter type="envmap"><string name="filename" value="../scenes/textures/sky-64x32.exr"/></emitter>"#,
    );
    let si_up = reference_point(Vec3::ZERO, Vec3::Y);
    let (nt, np) = (400, 800);
    let mut exact = 0.0;
    for i in 0..nt {
        let ct = (i as f64 + 0.5) / nt as f64;
        let st = (1.0 - ct * ct).sqrt();
        for j in 0..np {
            let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
            let d = Vec3::new((st * phi.cos()) as f32, ct as f32, (st * phi.sin()) as f32);
            exact += s
                .scene
                .eval_environment(d, penumbra::spectrum::NO_WAVELENGTHS)
                .x as f64
                * ct;
        }
    }
    exact *= 2.0 * PI / (nt * np) as f64;
    assert_irradiance("envmap", nee_irradiance(&s, &si_up, 400_000, 14), exact);
}

#[test]
fn delta_lights_give_mitsubas_values() {
    let si = reference_point(Vec3::ZERO, Vec3::Z);
    // Point: I / r² (Mitsuba 3.9.1: intensity 3 at distance 2 gives 0.75).
    let s = scene(
        r#"<emitter type="point"><point name="position" value="0, 0, 2"/><float name="intensity" value="3"/></emitter>"#,
    );
    let ds = s
        .scene
        .sample_emitter_direction(&si, Vec2::splat(0.5), penumbra::spectrum::NO_WAVELENGTHS)
        .unwrap();
    assert!(ds.delta && ds.pdf == 1.0 && (ds.dist - 2.0).abs() < 1e-6);
    assert!((ds.radiance - Spectrum::splat(0.75)).abs().max_element() < 1e-6);
    assert!((ds.d - Vec3::Z).length() < 1e-6);
    // The shadow ray ends a relative SHADOW_EPSILON short of the light, leaving from the
    // offset surface point.
    let ray = Scene::shadow_ray(&si, &ds);
    let end = ray.at(ray.tmax / (1.0 - penumbra::geometry::SHADOW_EPSILON));
    assert!((end - Vec3::new(0.0, 0.0, 2.0)).length() < 1e-6);
    // Spot (cutoff 20°, beam 15°), at distance 2 and angle θ from its axis; Mitsuba 3.9.1's
    // values of intensity · falloff: 1 up to 15°, 0.8 at 16°, 0.4 at 18°, 0.02 at 19.9°, 0
    // beyond 20°.
    let s = scene(r#"<emitter type="spot"><float name="intensity" value="1"/></emitter>"#);
    for (deg, expected) in [
        (0.0, 1.0),
        (10.0, 1.0),
        (14.0, 1.0),
        (16.0, 0.8),
        (18.0, 0.4),
        (19.9, 0.02),
        (20.1, 0.0),
    ] {
        let a = (deg as f32).to_radians();
        let p = Vec3::new(a.sin() * 2.0, 0.0, a.cos() * 2.0);
        let si = reference_point(p, -Vec3::Z);
        let got = s
            .scene
            .sample_emitter_direction(&si, Vec2::splat(0.5), penumbra::spectrum::NO_WAVELENGTHS)
            .map_or(0.0, |ds| ds.radiance.x * 4.0);
        assert!(
            (got - expected).abs() < 2e-4,
            "spot at {deg}°: {got} vs {expected}"
        );
    }
    // Directional: irradiance E from the opposite of its direction, shadow ray to ∞.
    let s = scene(
        r#"<emitter type="directional"><vector name="direction" value="0, 0, -1"/><float name="irradiance" value="2"/></emitter>"#,
    );
    let ds = s
        .scene
        .sample_emitter_direction(&si, Vec2::splat(0.3), penumbra::spectrum::NO_WAVELENGTHS)
        .unwrap();
    assert!(ds.delta && ds.is_infinite() && (ds.d - Vec3::Z).length() < 1e-6);
    assert_eq!(ds.radiance, Spectrum::splat(2.0));
    assert_eq!(Scene::shadow_ray(&si, &ds).tmax, f32::INFINITY);
}

#[test]
fn environment_seen_by_camera_rays_unless_emitters_are_hidden() {
    let xml = |hide: bool| {
        format!(
            r#"<scene version="3.0.0">
    <integrator type="path"><boolean name="hide_emitters" value="{hide}"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="0.25, 0.5, 1"/></emitter>
</scene>"#
        )
    };
    let img = render_scene(&scene_from_str(&xml(false)), 2, 0, None)
        .film
        .image();
    assert!(img.iter().all(|p| *p == [0.25, 0.5, 1.0]));
    // Mitsuba: with hide_emitters, camera rays that leave the scene return 0.
    let img = render_scene(&scene_from_str(&xml(true)), 2, 0, None)
        .film
        .image();
    assert!(img.iter().all(|p| *p == [0.0; 3]));
}

/// `Emitter::power` (the weights light tracing will choose emitters by) against the closed
/// forms: π A L for a one-sided area light, 4π I for a point, 2π(1 − cos θ) I for a spot
/// with θ halfway between beam and cutoff, π r² E for a directional light and π · π r² L for
/// a constant environment, both over the bounding disk of radius r.
#[test]
fn emitter_power_closed_forms() {
    let s = scene(
        r#"<shape type="rectangle">
            <transform name="to_world"><scale x="2" y="0.5"/></transform>
            <emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>
        </shape>
        <emitter type="point"><point name="position" x="0" y="0" z="1"/><rgb name="intensity" value="3, 3, 6"/></emitter>
        <emitter type="spot"><float name="intensity" value="2"/><float name="cutoff_angle" value="30"/><float name="beam_width" value="10"/></emitter>
        <emitter type="directional"><vector name="direction" x="0" y="0" z="-1"/><float name="irradiance" value="1.5"/></emitter>"#,
    );
    let r = 2.5;
    let pi = PI;
    let mid = 20f64.to_radians();
    let expected = [
        pi * (2.0 * 2.0 * 0.5 * 2.0) * 2.0,
        4.0 * pi * 4.0,
        2.0 * pi * (1.0 - mid.cos()) * 2.0,
        pi * r * r * 1.5,
    ];
    assert_eq!(s.scene.emitters.len(), expected.len());
    for (e, want) in s.scene.emitters.iter().zip(expected) {
        let got = e.power(&s.scene.shapes, r);
        assert!(
            (got / want - 1.0).abs() < 1e-5,
            "{e:?}: power {got}, expected {want}"
        );
    }
    let s =
        scene(r#"<emitter type="constant"><rgb name="radiance" value="0.5, 1, 1.5"/></emitter>"#);
    let got = s.scene.emitters[0].power(&s.scene.shapes, r);
    let want = pi * pi * r * r;
    assert!((got / want - 1.0).abs() < 1e-5, "constant: {got} vs {want}");
    // projector: π × mean irradiance × scale × the image's area at distance 1,
    // (2 tan(fov_x / 2))² / aspect = 4 for a square 90° image
    let s = scene(
        r#"<emitter type="projector"><rgb name="irradiance" value="0.5, 1, 1.5"/><float name="scale" value="3"/><float name="fov" value="90"/></emitter>"#,
    );
    let got = s.scene.emitters[0].power(&s.scene.shapes, r);
    let want = pi * 3.0 * 4.0;
    assert!(
        (got / want - 1.0).abs() < 1e-5,
        "projector: {got} vs {want}"
    );
}

/// Light tracing starts its paths with `Emitter::sample_ray`, whose weight is emitted
/// radiance × measurement / density: its mean is the emitted power, known in closed form
/// (per channel): area π A L (A = 4 here), point 4π I, spot 2π I ∫ falloff(θ) sin θ dθ
/// (the integral by Simpson's rule over Mitsuba's linear falloff, beam 10°, cutoff 30°),
/// projector π · scale · E · A (A = 4: a square 90° image), directional π r² E and constant
/// 4π · π r² L (r the scene's bounding radius). 400,000 rays each, z-test of the mean,
/// Šidák α = 0.01 over 18 channel means; every sample's weight must be finite and every
/// ray's direction a unit vector (and the directional light's its direction).
#[test]
fn emitter_rays_carry_the_emitted_power() {
    let s = scene(
        r#"<shape type="rectangle">
            <transform name="to_world"><scale x="2" y="0.5"/></transform>
            <emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>
        </shape>
        <emitter type="point"><point name="position" x="0" y="0" z="1"/><rgb name="intensity" value="3, 3, 6"/></emitter>
        <emitter type="spot"><float name="intensity" value="2"/><float name="cutoff_angle" value="30"/><float name="beam_width" value="10"/></emitter>
        <emitter type="projector"><rgb name="irradiance" value="0.5, 1, 1.5"/><float name="scale" value="3"/><float name="fov" value="90"/></emitter>
        <emitter type="directional"><vector name="direction" x="0" y="0.6" z="-0.8"/><float name="irradiance" value="1.5"/></emitter>
        <emitter type="constant"><rgb name="radiance" value="0.5, 1, 1.5"/></emitter>"#,
    );
    let r = s.scene.bounding_sphere.1 as f64;
    let (beam, cutoff) = (10f64.to_radians(), 30f64.to_radians());
    let falloff = |t: f64| {
        if t <= beam {
            1.0
        } else {
            ((cutoff - t) / (cutoff - beam)).max(0.0)
        }
    };
    let cone = simpson(|t| falloff(t) * t.sin(), 0.0, cutoff, 100_000);
    let v = |x: f64, y: f64, z: f64| [x, y, z];
    let expected = [
        v(PI * 4.0, PI * 8.0, PI * 12.0),
        v(4.0 * PI * 3.0, 4.0 * PI * 3.0, 4.0 * PI * 6.0),
        [2.0 * PI * 2.0 * cone; 3],
        v(PI * 3.0 * 0.5 * 4.0, PI * 3.0 * 4.0, PI * 3.0 * 1.5 * 4.0),
        [PI * r * r * 1.5; 3],
        v(
            4.0 * PI * PI * r * r * 0.5,
            4.0 * PI * PI * r * r,
            4.0 * PI * PI * r * r * 1.5,
        ),
    ];
    assert_eq!(s.scene.emitters.len(), expected.len());
    let z_crit = normal_critical_z(sidak(0.01, 3 * expected.len()));
    for (i, (e, want)) in s.scene.emitters.iter().zip(expected).enumerate() {
        let n = 400_000;
        let (mut sum, mut sum_sq) = ([0.0f64; 3], [0.0f64; 3]);
        let mut rng = SampleStream::new(0xe41, i as u64, 0);
        for _ in 0..n {
            let Some(er) = e.sample_ray(
                rng.next_2d(),
                rng.next_2d(),
                &s.scene.shapes,
                s.scene.bounding_sphere,
                penumbra::spectrum::NO_WAVELENGTHS,
            ) else {
                continue;
            };
            assert!(er.weight.is_finite(), "{e:?}: weight {}", er.weight);
            assert!(
                (er.ray.d.length() - 1.0).abs() < 1e-5,
                "{e:?}: {:?}",
                er.ray.d
            );
            if let Emitter::Directional(d) = e {
                assert!((er.ray.d - d.direction).length() < 1e-5);
            }
            for c in 0..3 {
                let w = er.weight[c] as f64;
                sum[c] += w;
                sum_sq[c] += w * w;
            }
        }
        for c in 0..3 {
            let mean = sum[c] / n as f64;
            let var = (sum_sq[c] / n as f64 - mean * mean).max(0.0);
            // (a constant weight has no variance: allow f32 rounding)
            let se = (var / n as f64).sqrt().max(1e-6 * want[c]);
            let z = (mean - want[c]).abs() / se;
            assert!(
                z < z_crit,
                "{e:?} channel {c}: mean weight {mean}, power {} (z = {z})",
                want[c]
            );
        }
    }
}

/// A textured area light's position sampling (where light paths start: ptracer, bdpt) gives
/// the density `pdf_position` gives for the same point, p_uv / |∂p/∂u × ∂p/∂v|: on a
/// rectangle scaled by 3 the Jacobian is 36, so a density multiplied by it instead of
/// divided is 1296 times off.
#[test]
fn textured_area_light_positions_have_pdf_positions_density() {
    let s = scene(
        r#"<shape type="rectangle">
               <transform name="to_world"><scale value="3"/></transform>
               <emitter type="area">
                   <texture type="checkerboard" name="radiance">
                       <rgb name="color0" value="0.2"/> <rgb name="color1" value="3"/>
                   </texture>
               </emitter>
           </shape>"#,
    );
    let Emitter::Area(a) = &s.scene.emitters[0] else {
        panic!("an area emitter")
    };
    let mut checked = 0;
    for k in 0..64 {
        let u = Vec2::new((k as f32 + 0.5) / 64.0, (k as f32 * 0.618_034).fract());
        let Some(pos) = a.sample_position(u, &s.scene.shapes, penumbra::spectrum::NO_WAVELENGTHS)
        else {
            continue;
        };
        // the same point as a surface interaction: from above, along −z
        let hit = s
            .scene
            .intersect(&Ray::new(pos.p + Vec3::Z, -Vec3::Z, f32::INFINITY))
            .expect("the sampled point is on the rectangle");
        let want = a.pdf_position(&hit, &s.scene.shapes);
        assert!(
            (pos.pdf / want - 1.0).abs() < 1e-3,
            "u {u}: sample_position's density {} against pdf_position's {want}",
            pos.pdf
        );
        checked += 1;
    }
    assert!(checked >= 60, "only {checked} positions sampled");
}
