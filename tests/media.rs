//! Participating media against analytic truth: the phase functions' sampling (chi-square),
//! transmittance through homogeneous and heterogeneous slabs (delta tracking on camera rays,
//! ratio tracking on shadow rays) against exp(−∫σt), a camera inside a medium, and furnaces
//! (an albedo-1 medium, bare or behind a dielectric, in a uniform environment stays at the
//! environment's radiance), a grid varying along every axis pixel by pixel, `wrap_mode`
//! beyond the grid, and single scattering with 0 < albedo < 1 (closed form and quadrature,
//! with and without emitter sampling). Each render is z-tested per channel with the image's
//! standard error, Šidák-corrected over all the z-tests of its test (α = 0.01), and must not
//! have dropped a non-finite sample.

mod common;

use common::*;
use glam::Vec3;
use penumbra::phase::{HenyeyGreenstein, PhaseFunction};
use penumbra::render::Job;
use penumbra::sampler::SampleStream;
use penumbra::study::chi2::{chi2_test_adaptive, Chi2Config};
use penumbra::study::stats::{normal_critical_z, sidak};

/// `volpathmis-hero` is volpathmis without spectral MIS (`use_spectral_mis` false).
const INTEGRATORS: [&str; 3] = ["volpath", "volpathmis", "volpathmis-hero"];

/// An orthographic camera at z = 5 looking down −z over [−0.8, 0.8]², 8 × 8 box-filtered
/// pixels, the given integrator; `body` adds the rest (before the sensor, so that the
/// sensor can refer to its media).
fn scene_xml(integrator: &str, max_depth: i32, sensor_extra: &str, body: &str) -> String {
    let (integrator, extra) = match integrator {
        "volpathmis-hero" => (
            "volpathmis",
            r#"<boolean name="use_spectral_mis" value="false"/>"#,
        ),
        other => (other, ""),
    };
    format!(
        r#"<scene version="3.0.0">
            <integrator type="{integrator}"><integer name="max_depth" value="{max_depth}"/>{extra}</integrator>
            {body}
            <sensor type="orthographic">
                <float name="near_clip" value="0.0001"/>
                <transform name="to_world">
                    <scale value="0.8, 0.8, 1"/>
                    <lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>
                </transform>
                <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
                    <rfilter type="box"/></film>
                <sampler type="independent"/>
                {sensor_extra}
            </sensor>
        </scene>"#
    )
}

/// The image mean of `xml` rendered at `spp` and its standard error. A render whose
/// integrator made a non-finite sample fails here: such samples are dropped before the film,
/// so the mean alone would not show them.
fn render_mean(xml: &str, spp: u32) -> ([f64; 3], [f64; 3]) {
    let scene = scene_from_str(xml);
    let out = render_scene(&scene, spp, 7, None);
    assert_eq!(out.stats.nonfinite, 0, "non-finite samples dropped");
    image_mean_and_se(&out, spp)
}

/// Collects z-test failures: `|mean − expected| > z · se` per channel.
struct ZTests {
    z: f64,
    failures: Vec<String>,
    count: usize,
}

impl ZTests {
    fn new(tests: usize) -> Self {
        ZTests {
            z: normal_critical_z(sidak(0.01, tests)),
            failures: Vec::new(),
            count: 0,
        }
    }

    fn check(&mut self, what: &str, (mean, se): ([f64; 3], [f64; 3]), expected: [f64; 3]) {
        for c in 0..3 {
            self.count += 1;
            let z = (mean[c] - expected[c]) / se[c];
            println!(
                "{what} ch{c}: {:.5} ± {:.5}, expected {:.5} (z = {z:+.2})",
                mean[c], se[c], expected[c]
            );
            let ok = z.abs() <= self.z && se[c] < 0.05 * expected[c].max(0.05);
            if !ok {
                self.failures.push(format!(
                    "{what} channel {c}: {:.5} ± {:.5}, expected {:.5} (|z| = {:.2} > {:.2} or se too large)",
                    mean[c],
                    se[c],
                    expected[c],
                    z.abs(),
                    self.z
                ));
            }
        }
    }

    fn finish(self, planned: usize) {
        assert_eq!(self.count, planned, "every planned z-test ran");
        assert!(self.failures.is_empty(), "{}", self.failures.join("\n"));
    }
}

#[test]
fn phase_functions_sample_their_density() {
    let phases = [
        PhaseFunction::Isotropic,
        PhaseFunction::HenyeyGreenstein(HenyeyGreenstein { g: -0.7 }),
        PhaseFunction::HenyeyGreenstein(HenyeyGreenstein { g: 0.0 }),
        PhaseFunction::HenyeyGreenstein(HenyeyGreenstein { g: 0.3 }),
        PhaseFunction::HenyeyGreenstein(HenyeyGreenstein { g: 0.9 }),
    ];
    let wis = [
        Vec3::Z,
        Vec3::new(0.3, -0.5, 0.81).normalize(),
        Vec3::new(-1.0, 0.2, -0.1).normalize(),
    ];
    let tests = phases.len() * wis.len();
    let alpha = sidak(0.01, tests);
    let cfg = Chi2Config {
        cos_theta_bins: 20,
        phi_bins: 40,
        ..Chi2Config::default()
    };
    let mut failures = Vec::new();
    for (k, phase) in phases.iter().enumerate() {
        for (j, wi) in wis.iter().enumerate() {
            let mut bad = 0;
            let r = chi2_test_adaptive(
                200_000,
                |i| {
                    let u = SampleStream::new(11 + k as u64, i as u64, j as u64).next_2d();
                    let s = phase.sample(*wi, u)?;
                    // weight = p / pdf and pdf = p at every sample.
                    let p = phase.eval(*wi, s.wo);
                    if (s.pdf - p).abs() > 1e-4 * p || (s.weight - 1.0).abs() > 1e-6 {
                        bad += 1;
                    }
                    if (s.wo.length() - 1.0).abs() > 1e-5 {
                        bad += 1;
                    }
                    Some(s.wo)
                },
                |d| phase.eval(*wi, d.normalize()) as f64,
                &cfg,
                1e-6,
            );
            println!("{phase:?} wi {wi}: {r:?}");
            if bad > 0 {
                failures.push(format!(
                    "{phase:?} wi {wi}: {bad} samples disagree with eval"
                ));
            }
            if r.p_value < alpha || (r.pdf_integral - 1.0).abs() > 1e-3 {
                failures.push(format!(
                    "{phase:?} wi {wi}: chi2 p = {:.3e} (α = {alpha:.1e}), ∫p = {:.5}",
                    r.p_value, r.pdf_integral
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // Henyey–Greenstein's mean cosine (of the angle to the forward direction −wi) is g.
    let hg = HenyeyGreenstein { g: 0.6 };
    let n = 400_000;
    let mean_cos: f64 = (0..n)
        .map(|i| {
            let u = SampleStream::new(5, i, 0).next_2d();
            hg.sample(Vec3::Z, u).wo.dot(-Vec3::Z) as f64
        })
        .sum::<f64>()
        / n as f64;
    // Var(cos θ) ≤ 1: se ≤ 1/√n = 0.0016.
    assert!(
        (mean_cos - 0.6).abs() < 4.0 * (1.0 / n as f64).sqrt(),
        "{mean_cos}"
    );
}

/// A unit-radiance constant environment seen through a 2-unit-thick cube of `medium`
/// (absorbing only: albedo 0): every pixel's expected value is exp(−τ) per channel.
fn slab_body(medium: &str) -> String {
    format!(
        r#"<emitter type="constant"><rgb name="radiance" value="1"/></emitter>
           {medium}
           <shape type="cube"><bsdf type="null"/><ref id="m" name="interior"/></shape>"#
    )
}

fn vol_file(name: &str, res: [usize; 3], channels: usize, data: &[f32]) -> String {
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let bytes = penumbra::io::vol::write_vol(res, channels, [[0.0; 3], [1.0; 3]], data);
    std::fs::write(&path, bytes).expect("write the grid");
    path.display().to_string()
}

/// A heterogeneous medium over the cube [−1, 1]³ whose σt varies along z through three
/// texels (trilinear between their centres, clamped beyond), grey or RGB: the optical depth
/// along z through the cube is 2 · (mean of the three texels) per channel.
fn hetero_medium(rgb: bool) -> (String, [f64; 3]) {
    let texels: [[f32; 3]; 3] = if rgb {
        [[0.2, 1.0, 2.0], [3.0, 0.5, 1.0], [1.0, 1.0, 0.1]]
    } else {
        [[0.2; 3], [3.0; 3], [1.0; 3]]
    };
    let (file, data): (&str, Vec<f32>) = if rgb {
        ("media_rgb.vol", texels.iter().flatten().copied().collect())
    } else {
        ("media_grey.vol", texels.iter().map(|t| t[0]).collect())
    };
    let path = vol_file(file, [1, 1, 3], if rgb { 3 } else { 1 }, &data);
    let tau = |c: usize| 2.0 * texels.iter().map(|t| t[c] as f64).sum::<f64>() / 3.0;
    let xml = format!(
        r#"<medium type="heterogeneous" id="m">
               <volume name="sigma_t" type="gridvolume">
                   <string name="filename" value="{path}"/>
                   <transform name="to_world"><scale value="2"/><translate value="-1, -1, -1"/></transform>
               </volume>
               <rgb name="albedo" value="0"/>
           </medium>"#
    );
    (xml, [tau(0), tau(1), tau(2)])
}

#[test]
fn slab_transmittance_is_exp_of_optical_depth() {
    let homogeneous = r#"<medium type="homogeneous" id="m">
            <rgb name="sigma_t" value="0.25, 0.5, 1"/> <float name="scale" value="1.5"/>
            <rgb name="albedo" value="0"/>
        </medium>"#;
    let tau_homo = [0.75, 1.5, 3.0];
    let (grey, tau_grey) = hetero_medium(false);
    let (rgb, tau_rgb) = hetero_medium(true);
    let cases = [
        ("homogeneous", homogeneous.to_string(), tau_homo),
        ("heterogeneous grey", grey, tau_grey),
        ("heterogeneous rgb", rgb, tau_rgb),
    ];
    let mut z = ZTests::new(cases.len() * INTEGRATORS.len() * 3);
    for (name, medium, tau) in &cases {
        for integrator in INTEGRATORS {
            let xml = scene_xml(integrator, -1, "", &slab_body(medium));
            let expected = tau.map(|t| (-t).exp());
            z.check(
                &format!("{integrator} {name}"),
                render_mean(&xml, 4096),
                expected,
            );
        }
    }
    z.finish(cases.len() * INTEGRATORS.len() * 3);
}

/// A directional light of irradiance π along −z, `medium` (id "m") filling a null cube of
/// half-size `container` about the origin, and a white diffuse plane at z = −2 inside it.
fn lit_plane_in_medium(medium: &str, container: f64) -> String {
    format!(
        r#"<emitter type="directional">
               <vector name="direction" value="0, 0, -1"/>
               <rgb name="irradiance" value="3.14159265358979"/>
           </emitter>
           {medium}
           <shape type="cube"><transform name="to_world"><scale value="{container}"/></transform>
               <bsdf type="null"/><ref id="m" name="interior"/></shape>
           <shape type="rectangle">
               <transform name="to_world"><scale value="3"/><translate value="0, 0, -2"/></transform>
               <bsdf type="diffuse"><rgb name="reflectance" value="1"/></bsdf>
           </shape>"#
    )
}

/// A white diffuse plane behind the slab, lit straight along −z by a directional light of
/// irradiance π through the slab, seen along −z through the slab, direct light only: the
/// pixel is T_camera · T_shadow = exp(−2τ), the camera ray delta-tracked and the shadow ray
/// ratio-tracked (heterogeneous) or track-length estimated (homogeneous).
#[test]
fn shadow_rays_carry_the_slab_transmittance() {
    let homogeneous = r#"<medium type="homogeneous" id="m">
            <rgb name="sigma_t" value="0.2, 0.4, 0.6"/> <rgb name="albedo" value="0"/>
        </medium>"#;
    let (grey, tau_grey) = hetero_medium(false);
    let (rgb, tau_rgb) = hetero_medium(true);
    let cases = [
        ("homogeneous", homogeneous.to_string(), [0.4, 0.8, 1.2]),
        ("heterogeneous grey", grey, tau_grey),
        ("heterogeneous rgb", rgb, tau_rgb),
    ];
    let mut z = ZTests::new(cases.len() * INTEGRATORS.len() * 3);
    for (name, medium, tau) in &cases {
        for integrator in INTEGRATORS {
            let body = lit_plane_in_medium(medium, 1.0);
            let xml = scene_xml(integrator, 2, "", &body);
            let expected = tau.map(|t| (-2.0 * t).exp());
            z.check(
                &format!("{integrator} {name}"),
                render_mean(&xml, 4096),
                expected,
            );
        }
    }
    z.finish(cases.len() * INTEGRATORS.len() * 3);
}

/// A shadow ray ends at the light. Where shadow rays must see through null surfaces (here a
/// null cube off to the side turns that on), they are traced segment by segment up to the
/// light's distance; one that ran on past a point light would be blocked by the ceiling
/// above it. A white plane lit by a point light of intensity I at height h = 1, seen
/// through an orthographic camera whose rays start below the ceiling (near clip), direct
/// light only: the image mean over the visible square [−a, a]² is ρ I Ω / (π (2a)²), with Ω
/// = 4 atan(a² / (h √(h² + 2a²))) the solid angle of the square seen from the light
/// (∫ h / r³ dA over the square).
#[test]
fn shadow_rays_through_null_surfaces_end_at_the_light() {
    let (a, h, intensity) = (0.8f64, 1.0f64, 5.0f64);
    let omega = 4.0 * (a * a / (h * (h * h + 2.0 * a * a).sqrt())).atan();
    let expected = intensity * omega / (std::f64::consts::PI * 4.0 * a * a);
    let mut z = ZTests::new(INTEGRATORS.len() * 3);
    for integrator in INTEGRATORS {
        let body = format!(
            r#"<emitter type="point"><point name="position" x="0" y="0" z="{h}"/>
                   <rgb name="intensity" value="{intensity}"/></emitter>
               <shape type="cube"><transform name="to_world"><scale value="0.1"/><translate value="2.5, 2.5, 0.5"/></transform>
                   <bsdf type="null"/></shape>
               <shape type="rectangle">
                   <transform name="to_world"><scale value="3"/></transform>
                   <bsdf type="diffuse"><rgb name="reflectance" value="1"/></bsdf>
               </shape>
               <shape type="rectangle">
                   <transform name="to_world"><scale value="3"/><rotate x="1" angle="180"/><translate value="0, 0, 2"/></transform>
                   <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
               </shape>"#
        );
        // The camera at z = 5 with its rays starting 3.5 below it, under the ceiling at z = 2.
        let xml = scene_xml(integrator, 2, "", &body).replace(
            r#"<float name="near_clip" value="0.0001"/>"#,
            r#"<float name="near_clip" value="3.5"/>"#,
        );
        z.check(integrator, render_mean(&xml, 64), [expected; 3]);
    }
    z.finish(INTEGRATORS.len() * 3);
}

/// A camera inside an unbounded absorbing medium (the sensor's medium) sees an emitter 1
/// unit away through it: exp(−σt).
#[test]
fn camera_rays_start_in_the_sensor_medium() {
    let mut z = ZTests::new(INTEGRATORS.len() * 3);
    for integrator in INTEGRATORS {
        let body = r#"<medium type="homogeneous" id="m">
                <rgb name="sigma_t" value="0.25, 0.5, 1"/> <float name="scale" value="2"/>
                <rgb name="albedo" value="0"/>
            </medium>
            <shape type="rectangle">
                <transform name="to_world"><scale value="3"/><translate value="0, 0, 4"/></transform>
                <emitter type="area"><rgb name="radiance" value="1"/></emitter>
            </shape>"#;
        let xml = scene_xml(integrator, -1, r#"<ref id="m"/>"#, body);
        let expected = [0.5f64, 1.0, 2.0].map(|s| (-s * (1.0 - 1e-4)).exp());
        z.check(integrator, render_mean(&xml, 4096), expected);
    }
    z.finish(INTEGRATORS.len() * 3);
}

/// Furnaces: a medium that scatters without absorbing (albedo 1), in a sphere under a
/// uniform environment of radiance 1, leaves every radiance at 1, with an index-matched
/// (null) boundary or a dielectric one, for chromatic homogeneous and heterogeneous media
/// and an anisotropic phase function. Paths are unbounded (Russian roulette only).
///
/// `volpath` behind a dielectric is tested with a grey medium only: with a chromatic σt its
/// per-channel weights (transmittance over the tracked channel's density, multiplied over
/// the many internal reflections) are heavy-tailed, so a render's mean sits low with rare
/// large outliers and its standard error is unreliable. Mitsuba's volpath does the same on
/// this scene (measured, 8 × 8 px, 16384 spp, seeds 0–2: R 0.986 / 0.983 / 0.992, B 0.941 /
/// 0.950 / 0.969; its volpathmis 1.000 ± 0.002); `volpathmis`'s spectral MIS is the remedy
/// and is tested on it here.
#[test]
fn albedo_one_media_in_a_uniform_environment_are_invisible() {
    let (grid, _) = hetero_medium(true);
    let grid = grid.replace(
        r#"<rgb name="albedo" value="0"/>"#,
        r#"<rgb name="albedo" value="1"/>"#,
    );
    let medium = |sigma_t: &str| {
        format!(
            r#"<medium type="homogeneous" id="m">
                   <rgb name="sigma_t" value="{sigma_t}"/> <float name="scale" value="2"/>
                   <rgb name="albedo" value="1"/>
                   <phase type="hg"><float name="g" value="0.6"/></phase>
               </medium>"#
        )
    };
    let chromatic = medium("0.25, 0.5, 1");
    let grey = medium("0.5");
    let cases = [
        (
            "volpath",
            "homogeneous rgb hg, null boundary",
            &chromatic,
            "null",
        ),
        (
            "volpathmis",
            "homogeneous rgb hg, null boundary",
            &chromatic,
            "null",
        ),
        (
            "volpath",
            "homogeneous grey hg, dielectric boundary",
            &grey,
            "dielectric",
        ),
        (
            "volpathmis",
            "homogeneous rgb hg, dielectric boundary",
            &chromatic,
            "dielectric",
        ),
        ("volpath", "heterogeneous rgb, null boundary", &grid, "null"),
        (
            "volpathmis",
            "heterogeneous rgb, null boundary",
            &grid,
            "null",
        ),
        // Without spectral MIS the channel weights are volpath's: grey behind the dielectric.
        (
            "volpathmis-hero",
            "homogeneous rgb hg, null boundary",
            &chromatic,
            "null",
        ),
        (
            "volpathmis-hero",
            "homogeneous grey hg, dielectric boundary",
            &grey,
            "dielectric",
        ),
        (
            "volpathmis-hero",
            "heterogeneous rgb, null boundary",
            &grid,
            "null",
        ),
    ];
    let mut z = ZTests::new(cases.len() * 3);
    for (integrator, name, medium, boundary) in cases {
        let body = format!(
            r#"<emitter type="constant"><rgb name="radiance" value="1"/></emitter>
               {medium}
               <shape type="sphere"><bsdf type="{boundary}"/><ref id="m" name="interior"/></shape>"#
        );
        let xml = scene_xml(integrator, -1, "", &body);
        z.check(
            &format!("{integrator} {name}"),
            render_mean(&xml, 1024),
            [1.0; 3],
        );
    }
    z.finish(cases.len() * 3);
}

/// Bad media input is refused with one line naming the problem, never a panic.
#[test]
fn bad_media_input_gets_one_clear_error() {
    let cases = [
        (
            r#"<medium type="fog" id="m"/>"#,
            "unsupported plugin <medium type=\"fog\">",
        ),
        (
            r#"<medium type="homogeneous" id="m"><phase type="hg"><float name="g" value="1"/></phase></medium>"#,
            "g of <phase type=\"hg\"> must lie in the interval (-1, 1)",
        ),
        (
            r#"<medium type="homogeneous" id="m"><rgb name="sigma_t" value="2, 1, 1"/></medium>"#,
            "invalid RGB reflectance value",
        ),
        (
            r#"<medium type="homogeneous" id="m"><float name="scale" value="-1"/></medium>"#,
            "scale of <medium type=\"homogeneous\"> must be >= 0",
        ),
        (
            r#"<medium type="heterogeneous" id="m"><volume name="sigma_t" type="gridvolume"><string name="filename" value="no-such.vol"/></volume></medium>"#,
            "no-such.vol",
        ),
        (
            r#"<medium type="heterogeneous" id="m"><volume name="sigma_t" type="gridvolume"><string name="filename" value="x.vol"/><string name="wrap_mode" value="wrap"/></volume></medium>"#,
            "invalid wrap_mode 'wrap'",
        ),
        (
            r#"<medium type="homogeneous" id="m"/><shape type="sphere"><ref id="m" name="inside"/></shape>"#,
            "must be named \"interior\" or \"exterior\"",
        ),
        (
            r#"<medium type="homogeneous" id="m"><phase type="rayleigh"/></medium>"#,
            "unsupported plugin <phase type=\"rayleigh\">",
        ),
    ];
    for (body, expected) in cases {
        let xml = scene_xml("volpath", -1, "", body);
        let e = match Job::from_xml_str(&xml, &repo_path("tests/inline.xml"), &[]) {
            Ok(_) => panic!("{body}: accepted"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains(expected), "{body}: {e}");
        assert!(!e.contains('\n'), "{body}: not one line: {e}");
    }
}

/// Mitsuba's depth semantics in both volumetric integrators: max_depth 1 shows only what
/// emits towards the camera (a lit plane stays exactly black), max_depth 2 adds direct light;
/// and the ray counter counts what was traced (at least one ray per path, at most the
/// camera ray plus two per scattering event, each through a null surface at most).
#[test]
fn max_depth_one_is_emission_only_and_rays_are_counted() {
    let light_and_plane = r#"<emitter type="directional">
               <vector name="direction" value="0, 0, -1"/>
               <rgb name="irradiance" value="1"/>
           </emitter>
           <shape type="rectangle">
               <transform name="to_world"><scale value="3"/><translate value="0, 0, -2"/></transform>
               <bsdf type="diffuse"/>
           </shape>"#;
    let with_medium = format!(
        r#"{light_and_plane}
           <medium type="homogeneous" id="m">
               <rgb name="sigma_t" value="0.5"/> <rgb name="albedo" value="0.5"/>
           </medium>
           <shape type="cube"><bsdf type="null"/><ref id="m" name="interior"/></shape>"#
    );
    // Without media or null surfaces shadow rays are plain occlusion tests: both paths.
    for (integrator, body, medium) in INTEGRATORS.iter().flat_map(|i| {
        [
            (*i, light_and_plane.to_string(), false),
            (*i, with_medium.clone(), true),
        ]
    }) {
        for max_depth in [1, 2, 5] {
            let scene = scene_from_str(&scene_xml(integrator, max_depth, "", &body));
            let out = render_scene(&scene, 16, 3, None);
            assert_eq!(out.stats.nonfinite, 0, "{integrator} max_depth {max_depth}");
            let image = out.film.image();
            let lit = image.iter().any(|p| p.iter().any(|&c| c > 0.0));
            assert_eq!(
                lit,
                max_depth > 1,
                "{integrator} max_depth {max_depth}: lit {lit}"
            );
            let s = out.stats;
            if !medium && max_depth <= 2 {
                // Every camera ray hits the plane: max_depth 1 traces it alone; 2 adds the
                // shadow ray and the escaping continuation.
                let per_path = if max_depth == 1 { 1 } else { 3 };
                assert_eq!(
                    s.path.rays,
                    per_path * s.paths,
                    "{integrator} max_depth {max_depth}"
                );
                // One (diffuse) bounce per path: the BSDF is sampled at the plane even when
                // max_depth then ends the path, as in Mitsuba.
                assert_eq!(
                    s.path.bounces, s.paths,
                    "{integrator} max_depth {max_depth}"
                );
            }
            // At most max_depth scattering events (surface or medium) per path, and with a
            // medium of albedo 0.5 in front of a lit plane some of them happen.
            assert!(
                s.path.bounces <= s.paths * max_depth as u64
                    && (max_depth == 1 || s.path.bounces > 0),
                "{integrator} max_depth {max_depth}: {} bounces for {} paths",
                s.path.bounces,
                s.paths
            );
            // Camera ray, then per scattering event (surface or medium) one shadow ray and
            // one continuation, each crossing the cube's two null faces at most.
            let bound = s.paths * (1 + 2 * 3 * max_depth as u64) * 3;
            assert!(
                s.path.rays >= s.paths && s.path.rays <= bound,
                "{integrator} max_depth {max_depth}: {} rays for {} paths",
                s.path.rays,
                s.paths
            );
        }
    }
}

/// A small grid of high majorant (σ̄ = 20 in its last texel, 0.1 wherever the rays go)
/// inside a container up to 8 times its size, lit and seen along z as in the test above:
/// the pixel is exp(−2 · 0.1 · 2) whatever the container's size. The majorant transmittance
/// of a segment is exp(−σ̄ t); measured from the grid's box to the container's far side
/// (t = 9 for the 8× container: σ̄ t = 180) it underflowed to 0 in f32 and tr/pdf became
/// 0/0: the image was black. Segments now stop at the box.
#[test]
fn a_dense_small_grid_in_a_large_container_keeps_its_shadow_rays() {
    let path = vol_file(
        "media_majorant.vol",
        [5, 1, 1],
        1,
        &[0.1, 0.1, 0.1, 0.1, 20.0],
    );
    let containers = [4.0, 8.0];
    let mut z = ZTests::new(containers.len() * INTEGRATORS.len() * 3);
    for container in containers {
        for integrator in INTEGRATORS {
            // The grid's box is x in [−1, 3], y and z in [−1, 1]; texel centres at x = −0.6,
            // 0.2, 1.0, 1.8, 2.6, so σt = 0.1 for x < 1.8, where the camera looks.
            let medium = format!(
                r#"<medium type="heterogeneous" id="m">
                       <volume name="sigma_t" type="gridvolume">
                           <string name="filename" value="{path}"/>
                           <transform name="to_world"><scale value="4, 2, 2"/><translate value="-1, -1, -1"/></transform>
                       </volume>
                       <rgb name="albedo" value="0"/>
                   </medium>"#
            );
            let body = lit_plane_in_medium(&medium, container);
            // The camera outside the largest container.
            let xml = scene_xml(integrator, 2, "", &body)
                .replace(r#"<lookat origin="0, 0, 5""#, r#"<lookat origin="0, 0, 9""#);
            z.check(
                &format!("{integrator} in a container of half-size {container}"),
                render_mean(&xml, 1024),
                [(-0.4f64).exp(); 3],
            );
        }
    }
    z.finish(containers.len() * INTEGRATORS.len() * 3);
}

/// Gauss–Legendre nodes and weights on [−1, 1], 5 points (exact for polynomials of degree 9).
const GL5: [(f64, f64); 5] = [
    (0.0, 0.568_888_888_888_888_9),
    (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
    (0.906_179_845_938_664, 0.236_926_885_056_189_1),
];

/// The pieces of [a, b] between the breakpoints that lie inside it.
fn pieces(a: f64, b: f64, breaks: &[f64]) -> Vec<(f64, f64)> {
    let mut cuts: Vec<f64> = breaks.iter().copied().filter(|&x| x > a && x < b).collect();
    cuts.sort_by(f64::total_cmp);
    let mut out = Vec::new();
    let mut lo = a;
    for c in cuts.into_iter().chain([b]) {
        out.push((lo, c));
        lo = c;
    }
    out
}

/// ∫_a^b f with 5-point Gauss–Legendre on each piece between `breaks`: exact for piecewise
/// polynomials of degree ≤ 9 that change only at the breakpoints.
fn integrate(a: f64, b: f64, breaks: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    pieces(a, b, breaks)
        .into_iter()
        .map(|(lo, hi)| {
            let (m, h) = (0.5 * (lo + hi), 0.5 * (hi - lo));
            GL5.iter().map(|(x, w)| w * h * f(m + h * x)).sum::<f64>()
        })
        .sum()
}

/// A grey grid of texel values `v` (x fastest, then y, then z: the `.vol` layout of Mitsuba's
/// `gridvolume`) on the unit cube, looked up in f64 as written in Mitsuba's documentation:
/// `nearest` takes the texel holding the point, `trilinear` weighs the texels whose centres
/// ((i + ½)/n per axis) surround it by tent functions, with texel indices beyond the grid
/// clamped or repeated.
struct GridModel {
    res: [usize; 3],
    v: Vec<f64>,
    trilinear: bool,
    repeat: bool,
}

impl GridModel {
    fn texel(&self, idx: [i64; 3]) -> f64 {
        let w = |i: i64, n: usize| {
            if self.repeat {
                i.rem_euclid(n as i64) as usize
            } else {
                i.clamp(0, n as i64 - 1) as usize
            }
        };
        let [nx, ny, nz] = self.res;
        let (i, j, k) = (w(idx[0], nx), w(idx[1], ny), w(idx[2], nz));
        self.v[(k * ny + j) * nx + i]
    }

    /// σt at local coordinates q ∈ [0, 1]³.
    fn sigma(&self, q: [f64; 3]) -> f64 {
        let n = self.res.map(|n| n as f64);
        if !self.trilinear {
            return self.texel([0, 1, 2].map(|a| (q[a] * n[a]).floor() as i64));
        }
        let p = [0, 1, 2].map(|a| q[a] * n[a] - 0.5);
        let lo = p.map(|x| x.floor() as i64);
        let mut sum = 0.0;
        for corner in 0..8 {
            let idx = [0, 1, 2].map(|a| lo[a] + ((corner >> a) & 1) as i64);
            let weight: f64 = (0..3)
                .map(|a| (1.0 - (p[a] - idx[a] as f64).abs()).max(0.0))
                .product();
            sum += weight * self.texel(idx);
        }
        sum
    }

    /// Where the lookup changes form along `axis`, in local coordinates: the texel centres
    /// (trilinear) or boundaries (nearest).
    fn breaks(&self, axis: usize) -> Vec<f64> {
        let n = self.res[axis];
        let off = if self.trilinear { 0.5 } else { 0.0 };
        (0..=n).map(|i| (i as f64 + off) / n as f64).collect()
    }
}

/// A slab transmittance image, pixel by pixel, through a grid that varies along all three
/// axes (3 × 2 × 4 texels, values not a sum of per-axis terms), so that the image depends on
/// the `.vol` layout's axis order (x fastest) and on the lookup: the absorbing grid fills the
/// cube [−1, 1]³ (seen along −z against a constant environment of radiance 1), and each
/// pixel is the mean over its footprint of exp(−τ(x, y)), τ = ∫ σt dz, computed here from
/// [`GridModel`] by Gauss–Legendre quadrature split where the lookup changes form. Three
/// lookups: trilinear and nearest with `clamp`, trilinear with `repeat` (which blends the
/// last texels into the first where the ray enters and leaves the grid; `mirror` equals
/// `clamp` inside the grid's box, and is tested beyond it below). Every pixel is z-tested
/// with its own variance (Šidák over all); each pair of expected images must differ by more
/// than twice the critical z somewhere, so a lookup that confused them would fail.
#[test]
fn grids_varying_along_every_axis_give_their_pixels_optical_depth() {
    let res = [3usize, 2, 4];
    let values: Vec<f64> = (0..24)
        .map(|n| {
            let (i, j, k) = (n % 3, (n / 3) % 2, n / 6);
            0.05 + 0.15 * i as f64
                + 0.25 * j as f64
                + 0.05 * k as f64
                + 0.1 * ((i + 2 * j + 3 * k) % 4) as f64
        })
        .collect();
    let data: Vec<f32> = values.iter().map(|&v| v as f32).collect();
    let path = vol_file("media_3x2x4.vol", res, 1, &data);
    let configs = [
        ("trilinear", "clamp"),
        ("nearest", "clamp"),
        ("trilinear", "repeat"),
    ];
    let spp = 4096;
    let pixels = 64;
    let z_crit = normal_critical_z(sidak(0.01, configs.len() * pixels));
    let mut expected_images = Vec::new();
    let mut failures = Vec::new();
    let mut ses = Vec::new();
    for (filter, wrap) in configs {
        let model = GridModel {
            res,
            v: values.clone(),
            trilinear: filter == "trilinear",
            repeat: wrap == "repeat",
        };
        let medium = format!(
            r#"<medium type="heterogeneous" id="m">
                   <volume name="sigma_t" type="gridvolume">
                       <string name="filename" value="{path}"/>
                       <string name="filter_type" value="{filter}"/>
                       <string name="wrap_mode" value="{wrap}"/>
                       <transform name="to_world"><scale value="2"/><translate value="-1, -1, -1"/></transform>
                   </volume>
                   <rgb name="albedo" value="0"/>
               </medium>"#
        );
        let scene = scene_from_str(&scene_xml("volpath", -1, "", &slab_body(&medium)));
        // World x, y ↦ local (x + 1)/2; τ(x, y) = 2 ∫₀¹ σt dw along the whole cube.
        let local = |x: f64| 0.5 * (x + 1.0);
        let world_breaks = |axis: usize| -> Vec<f64> {
            model.breaks(axis).iter().map(|b| 2.0 * b - 1.0).collect()
        };
        let (bx, by) = (world_breaks(0), world_breaks(1));
        let tau = |x: f64, y: f64| {
            2.0 * integrate(0.0, 1.0, &model.breaks(2), |w| {
                model.sigma([local(x), local(y), w])
            })
        };
        // Each pixel's footprint from the camera (orthographic: the rays' x and y).
        let expected: Vec<f64> = (0..pixels)
            .map(|i| {
                let (px, py) = ((i % 8) as f32, (i / 8) as f32);
                let a = scene
                    .scene
                    .camera
                    .generate_ray(glam::Vec2::new(px, py) / 8.0)
                    .o;
                let b = scene
                    .scene
                    .camera
                    .generate_ray(glam::Vec2::new(px + 1.0, py + 1.0) / 8.0)
                    .o;
                let (x0, x1) = (a.x.min(b.x) as f64, a.x.max(b.x) as f64);
                let (y0, y1) = (a.y.min(b.y) as f64, a.y.max(b.y) as f64);
                let area = (x1 - x0) * (y1 - y0);
                integrate(x0, x1, &bx, |x| {
                    integrate(y0, y1, &by, |y| (-tau(x, y)).exp())
                }) / area
            })
            .collect();
        let out = render_scene(&scene, spp, 7, None);
        assert_eq!(out.stats.nonfinite, 0, "{filter} {wrap}");
        let (img, var) = (out.film.image(), out.film.sample_variance());
        let mut worst = 0.0f64;
        for i in 0..pixels {
            let se = (var[i][0] as f64 / spp as f64).sqrt();
            let z = (img[i][0] as f64 - expected[i]) / se;
            worst = worst.max(z.abs());
            if z.abs() > z_crit {
                failures.push(format!(
                    "{filter} {wrap} pixel {i}: {} against {:.5} (z = {z:.2})",
                    img[i][0], expected[i]
                ));
            }
            ses.push(se);
        }
        println!("{filter} {wrap}: worst |z| {worst:.2} (bound {z_crit:.2})");
        expected_images.push(expected);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The three lookups give images this test tells apart.
    let se = ses.iter().copied().fold(0.0, f64::max);
    for a in 0..configs.len() {
        for b in a + 1..configs.len() {
            let d = (0..pixels)
                .map(|i| (expected_images[a][i] - expected_images[b][i]).abs())
                .fold(0.0, f64::max);
            assert!(
                d > 2.0 * z_crit * se,
                "{:?} and {:?} differ by at most {d:.4} (se {se:.4})",
                configs[a],
                configs[b]
            );
        }
    }
}

/// `wrap_mode` beyond the unit cube, against values worked out by hand. A 3 × 1 × 2 grid
/// holding 1, 2, 4 (z = 0) and 8, 16, 32 (z = 1), x fastest, looked up at local coordinates
/// (the volume's `to_world` is the identity and the camera sits at the origin). Along x at
/// z = ¼ (the first slice's centre): trilinear at x = 1.1 is 0.2 · v₂ + 0.8 · v₃ with texel
/// 3 clamped to 2 (4), repeated to 0 (1: 0.8 + 0.8 = 1.6) or mirrored to 2 (4); at x = −0.2
/// 0.1 · v₋₂ + 0.9 · v₋₁: clamp 1, repeat (2, 4) 3.8, mirror (2, 1) 1.1; at x = 1.9
/// 0.8 · v₅ + 0.2 · v₆: clamp 4, repeat (4, 1) 3.4, mirror (texels 0, 0) 1. Nearest at
/// x = 1.1 takes texel 3: 4, 1, 4; at x = −0.2 texel −1: 1, 4, 1; at x = 1.9 texel 5:
/// 4, 4, 1. Along z at x = ½ (texel 1's centre): trilinear at z = 1.3 is 0.9 · v₂ + 0.1 · v₃
/// of the column 2, 16: clamp 16, repeat (2, 16) 3.4, mirror (16, 2) 14.6; nearest at
/// z = 1.6 takes texel 3: 16, 16, 2.
#[test]
fn gridvolume_wrap_modes_beyond_the_unit_cube() {
    let path = vol_file(
        "media_wrap.vol",
        [3, 1, 2],
        1,
        &[1.0, 2.0, 4.0, 8.0, 16.0, 32.0],
    );
    // (filter, point, [clamp, repeat, mirror])
    let cases = [
        ("trilinear", [1.1, 0.5, 0.25], [4.0, 1.6, 4.0]),
        ("trilinear", [-0.2, 0.5, 0.25], [1.0, 3.8, 1.1]),
        ("trilinear", [1.9, 0.5, 0.25], [4.0, 3.4, 1.0]),
        ("trilinear", [0.5, 0.5, 1.3], [16.0, 3.4, 14.6]),
        ("nearest", [1.1, 0.5, 0.25], [4.0, 1.0, 4.0]),
        ("nearest", [-0.2, 0.5, 0.25], [1.0, 4.0, 1.0]),
        ("nearest", [1.9, 0.5, 0.25], [4.0, 4.0, 1.0]),
        ("nearest", [0.5, 0.5, 1.6], [16.0, 16.0, 2.0]),
    ];
    for (w, wrap) in ["clamp", "repeat", "mirror"].into_iter().enumerate() {
        for filter in ["trilinear", "nearest"] {
            let xml = format!(
                r#"<scene version="3.0.0">
                    <integrator type="volpath"/>
                    <medium type="heterogeneous" id="m">
                        <volume name="sigma_t" type="gridvolume">
                            <string name="filename" value="{path}"/>
                            <string name="filter_type" value="{filter}"/>
                            <string name="wrap_mode" value="{wrap}"/>
                        </volume>
                    </medium>
                    <shape type="cube"><bsdf type="null"/><ref id="m" name="interior"/></shape>
                    <sensor type="perspective"/>
                </scene>"#
            );
            let scene = scene_from_str(&xml);
            let sigma_t = match &scene.scene.media[0].kind {
                penumbra::medium::MediumKind::Heterogeneous(h) => &h.sigma_t,
                other => panic!("not heterogeneous: {other:?}"),
            };
            for (f, p, want) in cases.iter().filter(|c| c.0 == filter) {
                let got = sigma_t.eval_rgb(Vec3::new(p[0], p[1], p[2]));
                assert!(
                    (got - Vec3::splat(want[w])).abs().max_element() < 1e-5,
                    "{f} {wrap} at {p:?}: {got} against {}",
                    want[w]
                );
            }
        }
    }
}

/// Single scattering with 0 < albedo < 1, in closed form: a slab z ∈ [−1, 1] (wide in x and
/// y) of a homogeneous medium with chromatic σt and albedo a, Henyey–Greenstein phase g = 0.4,
/// lit by a directional light of irradiance E at θ = 30° from −z and seen along −z, with
/// max_depth 2 (one scattering event, its direct light). At depth s below the top the light
/// has come s / cos θ through the medium and the scattered light goes s back up:
/// L = a σt p E ∫₀² exp(−σt s (1 + 1/cos θ)) ds = a p E (1 − exp(−2 σt k)) / k,
/// k = 1 + 1/cos θ, with p = (1 − g²) / (4π (1 + g² − 2 g μ)^{3/2}) at the deflection cosine
/// μ = −cos θ between the light's direction and the camera's. Every pixel sees the same
/// value; the image mean is z-tested per channel (Šidák over all). A phase function with g's
/// sign or the angle's turned the wrong way, or a light transmittance along the wrong path,
/// misses it.
#[test]
fn single_scattering_of_a_directional_light_in_a_slab() {
    let sigma_t = [0.4f64, 0.8, 1.2];
    let albedo = [0.3f64, 0.5, 0.7];
    let (g, e, theta) = (0.4f64, 2.0f64, 30f64.to_radians());
    let mu = -theta.cos();
    let phase =
        (1.0 - g * g) / (4.0 * std::f64::consts::PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
    let k = 1.0 + 1.0 / theta.cos();
    let expected =
        [0, 1, 2].map(|c| albedo[c] * phase * e * (1.0 - (-2.0 * sigma_t[c] * k).exp()) / k);
    let body = format!(
        r#"<emitter type="directional">
               <vector name="direction" value="{}, 0, {}"/>
               <rgb name="irradiance" value="{e}"/>
           </emitter>
           <medium type="homogeneous" id="m">
               <rgb name="sigma_t" value="{}, {}, {}"/> <float name="scale" value="2"/>
               <rgb name="albedo" value="{}, {}, {}"/>
               <phase type="hg"><float name="g" value="{g}"/></phase>
           </medium>
           <shape type="cube"><transform name="to_world"><scale value="20, 20, 1"/></transform>
               <bsdf type="null"/><ref id="m" name="interior"/></shape>"#,
        theta.sin(),
        -theta.cos(),
        sigma_t[0] / 2.0,
        sigma_t[1] / 2.0,
        sigma_t[2] / 2.0,
        albedo[0],
        albedo[1],
        albedo[2],
    );
    let mut z = ZTests::new(INTEGRATORS.len() * 3);
    for integrator in INTEGRATORS {
        let xml = scene_xml(integrator, 2, "", &body);
        z.check(integrator, render_mean(&xml, 4096), expected);
    }
    z.finish(INTEGRATORS.len() * 3);
}

/// E₂(x) = ∫₀¹ exp(−x/μ) dμ, by Gauss–Legendre on 64 equal pieces (the integrand is smooth
/// on (0, 1] and flat towards 0).
fn e2(x: f64) -> f64 {
    let breaks: Vec<f64> = (1..64).map(|i| i as f64 / 64.0).collect();
    integrate(0.0, 1.0, &breaks, |mu| (-x / mu).exp())
}

/// Single scattering of a constant environment (radiance 1) in the same slab, isotropic
/// phase, max_depth 2, with the medium's `sample_emitters` true (next-event estimation and
/// phase sampling, weighed by MIS) and false (phase sampling alone): the same answer. At depth
/// s the in-scattered radiance is a σt / (4π) · 2π ∫ T dμ, with T = exp(−σt s / μ) towards
/// the top and exp(−σt (2 − s) / |μ|) towards the bottom, so with the environment seen straight
/// through the slab: L = exp(−2σt) + (a σt / 2) ∫₀² exp(−σt s) (E₂(σt s) + E₂(σt (2 − s))) ds,
/// by quadrature here. A path that weighed the environment it reaches by MIS against a
/// next-event estimate that `sample_emitters` false never made loses light.
#[test]
fn single_scattering_of_an_environment_with_and_without_emitter_sampling() {
    let sigma_t = [0.4f64, 0.8, 1.2];
    let albedo = [0.3f64, 0.5, 0.7];
    let breaks: Vec<f64> = (1..200).map(|i| i as f64 / 100.0).collect();
    let expected = [0, 1, 2].map(|c| {
        let (st, a) = (sigma_t[c], albedo[c]);
        let single = integrate(0.0, 2.0, &breaks, |s| {
            (-st * s).exp() * (e2(st * s) + e2(st * (2.0 - s)))
        });
        (-2.0 * st).exp() + 0.5 * a * st * single
    });
    let cases: Vec<(&str, bool)> = INTEGRATORS
        .iter()
        .flat_map(|&i| [(i, true), (i, false)])
        .collect();
    let mut z = ZTests::new(cases.len() * 3);
    for &(integrator, sample_emitters) in &cases {
        let body = format!(
            r#"<emitter type="constant"><rgb name="radiance" value="1"/></emitter>
               <medium type="homogeneous" id="m">
                   <rgb name="sigma_t" value="{}, {}, {}"/> <float name="scale" value="2"/>
                   <rgb name="albedo" value="{}, {}, {}"/>
                   <boolean name="sample_emitters" value="{sample_emitters}"/>
               </medium>
               <shape type="cube"><transform name="to_world"><scale value="20, 20, 1"/></transform>
                   <bsdf type="null"/><ref id="m" name="interior"/></shape>"#,
            sigma_t[0] / 2.0,
            sigma_t[1] / 2.0,
            sigma_t[2] / 2.0,
            albedo[0],
            albedo[1],
            albedo[2],
        );
        let xml = scene_xml(integrator, 2, "", &body);
        z.check(
            &format!("{integrator} sample_emitters {sample_emitters}"),
            render_mean(&xml, 4096),
            expected,
        );
    }
    z.finish(cases.len() * 3);
}
