//! Participating media against analytic truth: the phase functions' sampling (chi-square),
//! transmittance through homogeneous and heterogeneous slabs (delta tracking on camera rays,
//! ratio tracking on shadow rays) against exp(−∫σt), a camera inside a medium, and furnaces
//! (an albedo-1 medium, bare or behind a dielectric, in a uniform environment stays at the
//! environment's radiance). Each render is z-tested per channel with the image's standard
//! error, Šidák-corrected over all the z-tests of its test (α = 0.01).

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

/// The image mean of `xml` rendered at `spp` and its standard error.
fn render_mean(xml: &str, spp: u32) -> ([f64; 3], [f64; 3]) {
    let scene = scene_from_str(xml);
    let out = render_scene(&scene, spp, 7, None);
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
