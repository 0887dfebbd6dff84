//! `--mode spectral` against analytic answers (issue 43): scenes whose radiance is known at
//! every wavelength, so that the expected pixel is an integral over the visible range that
//! this test computes itself (fine quadrature of the CIE 1931 table as Mitsuba interpolates it,
//! `penumbra::spectrum::cie1931_xyz`, and Mitsuba's XYZ → linear sRGB matrix), independently
//! of the wavelength sampling, the upsampling and the film conversion under test.
//!
//! - A spectral furnace: a diffuse sphere with a strongly varying reflectance spectrum ρ(λ)
//!   under a uniform environment L; a convex Lambertian surface reflects ρ(λ) L at every λ.
//! - A white furnace per wavelength: the camera inside a sphere that emits Le(λ) = c (1 − ρ(λ))
//!   and reflects ρ(λ) (both piecewise linear on the same wavelengths, so Le/(1 − ρ) = c at
//!   every λ): the radiance is c everywhere, for each wavelength through a different number
//!   of bounces (ρ from 0.1 to 0.9).
//! - The spectral furnace through `aov`: its nested image and `albedo` converted from spectra
//!   (the albedo is ρ's colour under an equal-energy light, as Mitsuba's aov computes it), its
//!   depth the same numbers as in RGB mode.
//! - Both furnaces with `bdpt`: the two subpaths share the sample's wavelengths, and the
//!   light-tracing splats are converted with their weights.
//! - The spectral furnace again, traced from the light (`ptracer`), and lit by a black body
//!   (Planck's law at 5000 K, `<spectrum type="blackbody">`, spectral mode only).
//! - Transmittance per wavelength: the camera at the centre of a sphere of homogeneous,
//!   purely absorbing medium whose extinction σt(λ) varies 9-fold over the range, inside a
//!   uniform environment L: every ray crosses the radius R, so the radiance is
//!   L exp(−σt(λ) R). Distances are tracked at the path's first wavelength and the other three
//!   are weighed by their transmittance over its density, for `volpath` and `volpathmis`.
//! - A volumetric furnace: the same sphere filled with a heterogeneous, purely scattering
//!   medium (a constant volume with the same spectral σt, tracked against its largest value,
//!   so with null collisions): the radiance is L at every wavelength.
//!
//! Each image mean is z-tested against the integral with its standard error from the
//! per-pixel sample variances, Šidák-corrected over the 36 scene-channels. Both tests were
//! seen red with the film's value biased by 1% (z 7.7 and 9.2) and with the wavelength
//! weights (1 / pdf) replaced by a uniform density's 470 nm (z 167 and 151).

mod common;

use common::{image_mean_and_se, render_scene, repo_path};
use penumbra::render::Job;
use penumbra::scene::Scene;
use penumbra::spectrum::{cie1931_xyz, xyz_to_srgb, Mode, CIE_MAX, CIE_MIN, CIE_Y_NORMALIZATION};
use penumbra::study::stats::{normal_two_sided_p, sidak};

/// A piecewise linear spectrum over [360, 830] nm.
const RHO: &[(f64, f64)] = &[
    (360.0, 0.5),
    (420.0, 0.1),
    (480.0, 0.9),
    (540.0, 0.2),
    (600.0, 0.8),
    (660.0, 0.3),
    (720.0, 0.7),
    (830.0, 0.4),
];

fn at(list: &[(f64, f64)], w: f64) -> f64 {
    let i = list
        .partition_point(|(x, _)| *x <= w)
        .clamp(1, list.len() - 1);
    let ((x0, y0), (x1, y1)) = (list[i - 1], list[i]);
    y0 + (y1 - y0) * (w - x0) / (x1 - x0)
}

fn list_xml(list: &[(f64, f64)]) -> String {
    list.iter()
        .map(|(w, v)| format!("{w}:{v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Y_norm ∫ rgb(λ) f(λ) dλ over [360, 830] nm by the midpoint rule at 0.01 nm (the integrand
/// is piecewise quadratic with kinks every 5 nm: the rule's error is below 1e-7 relative).
fn expected_rgb(f: impl Fn(f64) -> f64) -> [f64; 3] {
    let n = 47_000;
    let h = (CIE_MAX - CIE_MIN) / n as f64;
    let mut xyz = glam::DVec3::ZERO;
    for k in 0..n {
        let w = CIE_MIN + (k as f64 + 0.5) * h;
        xyz += cie1931_xyz(w) * f(w) * h;
    }
    let rgb = xyz_to_srgb(xyz * CIE_Y_NORMALIZATION);
    [rgb.x, rgb.y, rgb.z]
}

/// Renders `xml` in spectral mode; returns the image mean and its standard error per channel.
fn render_mean(xml: &str, spp: u32) -> ([f64; 3], [f64; 3]) {
    render_mean_with(xml, spp, None)
}

/// [`render_mean`] with the scene's integrator switched to `integrator`.
fn render_mean_with(xml: &str, spp: u32, integrator: Option<&str>) -> ([f64; 3], [f64; 3]) {
    let xml = match integrator {
        Some(i) => xml.replace(
            r#"<integrator type="path""#,
            &format!(r#"<integrator type="{i}""#),
        ),
        None => xml.to_string(),
    };
    let mut desc =
        Scene::description_from_xml_str(&xml, &repo_path("tests/inline.xml"), &[]).expect("scene");
    desc.mode = Mode::Spectral;
    let out = render_scene(&Job::build(&desc).expect("build"), spp, 11, None);
    assert_eq!(out.stats.nonfinite, 0);
    image_mean_and_se(&out, spp)
}

fn check(name: &str, mean: [f64; 3], se: [f64; 3], expected: [f64; 3]) {
    let alpha = sidak(0.01, 36);
    for c in 0..3 {
        let z = (mean[c] - expected[c]) / se[c];
        println!(
            "{name} channel {c}: mean {:.6} expected {:.6} ({:+.3}%), z = {z:+.2}",
            mean[c],
            expected[c],
            100.0 * (mean[c] / expected[c] - 1.0)
        );
        assert!(
            se[c] > 0.0 && se[c] < 0.01 * expected[c].abs(),
            "{name}: se {}",
            se[c]
        );
        assert!(
            normal_two_sided_p(z.abs()) > alpha,
            "{name} channel {c}: mean {} vs expected {} (z = {z:.2})",
            mean[c],
            expected[c]
        );
    }
}

const SENSOR: &str = r#"<sensor type="perspective">
        <float name="fov" value="{fov}"/>
        <transform name="to_world"><lookat origin="{origin}" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/>
            <rfilter type="box"/></film>
        <sampler type="independent"/>
    </sensor>"#;

fn furnace_xml(l: f64) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="2"/></integrator>
    {}
    <emitter type="constant"><spectrum name="radiance" value="{l}"/></emitter>
    <shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="{}"/></bsdf></shape>
</scene>"#,
        SENSOR.replace("{fov}", "12").replace("{origin}", "0, 0, 5"),
        list_xml(RHO)
    )
}

#[test]
fn spectral_furnace_convex_sphere_reflects_rho_times_l() {
    let l = 0.8;
    let (mean, se) = render_mean(&furnace_xml(l), 256);
    check(
        "spectral furnace",
        mean,
        se,
        expected_rgb(|w| at(RHO, w) * l),
    );
}

/// The light tracer's splats carry the particle's four wavelengths and their weights.
#[test]
fn spectral_furnace_traced_from_the_light() {
    let l = 0.8;
    let (mean, se) = render_mean_with(&furnace_xml(l), 2048, Some("ptracer"));
    check(
        "spectral furnace, ptracer",
        mean,
        se,
        expected_rgb(|w| at(RHO, w) * l),
    );
}

/// bdpt in spectral mode, on both furnaces: every strategy (camera paths hitting the emitter,
/// next-event connections, light paths splatted onto the film) at the sample's wavelengths.
#[test]
fn bdpt_renders_both_furnaces_spectrally() {
    let l = 0.8;
    let (mean, se) = render_mean_with(&furnace_xml(l), 512, Some("bdpt"));
    check(
        "spectral furnace, bdpt",
        mean,
        se,
        expected_rgb(|w| at(RHO, w) * l),
    );
    let c = 0.5;
    let (mean, se) = render_mean_with(&white_furnace_xml(c), 128, Some("bdpt"));
    check(
        "white furnace per wavelength, bdpt",
        mean,
        se,
        expected_rgb(|_| c),
    );
}

/// The camera at the centre of a unit sphere of `medium` (index-matched boundary) inside a
/// uniform environment `l`.
fn medium_sphere_xml(medium: &str, integrator: &str, l: f64) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="{integrator}"/>
    {medium}
    {}
    <emitter type="constant"><spectrum name="radiance" value="{l}"/></emitter>
    <shape type="sphere"><bsdf type="null"/><ref name="interior" id="m"/></shape>
</scene>"#,
        SENSOR
            .replace("{fov}", "60")
            .replace(
                r#"origin="{origin}" target="0, 0, 0""#,
                r#"origin="0, 0, 0" target="0, 0, -1""#
            )
            // Rays start at the near clip plane, as Mitsuba's: 1e-6 instead of 0.01 keeps the
            // distance to the sphere 1 within 1e-6 (0.01 would shorten it by 1% or more).
            .replace(
                "<float name=\"fov\"",
                "<float name=\"near_clip\" value=\"1e-6\"/><float name=\"fov\""
            )
            .replace(
                r#"<sampler type="independent"/>"#,
                r#"<sampler type="independent"/><ref id="m"/>"#
            ),
    )
}

#[test]
fn absorbing_medium_transmits_exp_minus_sigma_t_r_per_wavelength() {
    let (l, scale) = (0.8, 2.0);
    let medium = format!(
        r#"<medium type="homogeneous" id="m">
        <spectrum name="sigma_t" value="{}"/>
        <float name="albedo" value="0"/>
        <float name="scale" value="{scale}"/>
    </medium>"#,
        list_xml(RHO)
    );
    for integrator in ["volpath", "volpathmis"] {
        let (mean, se) = render_mean(&medium_sphere_xml(&medium, integrator, l), 256);
        check(
            &format!("absorbing medium, {integrator}"),
            mean,
            se,
            expected_rgb(|w| l * (-scale * at(RHO, w)).exp()),
        );
    }
}

#[test]
fn scattering_heterogeneous_medium_is_a_furnace_at_every_wavelength() {
    let l = 0.8;
    // A constant volume covering [-2, 2]³ (its box is the unit cube under to_world).
    let medium = format!(
        r#"<medium type="heterogeneous" id="m">
        <volume type="constvolume" name="sigma_t">
            <spectrum name="value" value="{}"/>
            <transform name="to_world"><scale value="4"/><translate value="-2, -2, -2"/></transform>
        </volume>
        <float name="albedo" value="1"/>
        <float name="scale" value="1"/>
    </medium>"#,
        list_xml(RHO)
    );
    for integrator in ["volpath", "volpathmis"] {
        let (mean, se) = render_mean(&medium_sphere_xml(&medium, integrator, l), 512);
        check(
            &format!("volumetric furnace, {integrator}"),
            mean,
            se,
            expected_rgb(|_| l),
        );
    }
}

fn white_furnace_xml(c: f64) -> String {
    let le: Vec<(f64, f64)> = RHO.iter().map(|&(w, r)| (w, c * (1.0 - r))).collect();
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"/>
    {}
    <shape type="sphere">
        <boolean name="flip_normals" value="true"/>
        <bsdf type="diffuse"><spectrum name="reflectance" value="{}"/></bsdf>
        <emitter type="area"><spectrum name="radiance" value="{}"/></emitter>
    </shape>
</scene>"#,
        SENSOR
            .replace("{fov}", "60")
            .replace("{origin}", "0, 0, 0.1"),
        list_xml(RHO),
        list_xml(&le)
    )
}

#[test]
fn white_furnace_per_wavelength_inside_an_emitting_sphere() {
    let c = 0.5;
    let xml = white_furnace_xml(c);
    let (mean, se) = render_mean(&xml, 256);
    check(
        "white furnace per wavelength",
        mean,
        se,
        expected_rgb(|_| c),
    );
}

/// The integrators spectral mode renders build; the others are refused with one line naming
/// the integrator (docs/spectral.md says why each is RGB only).
#[test]
fn integrators_spectral_mode_renders_and_refuses() {
    let build = |integrator: &str| {
        let xml = furnace_xml(0.8).replace(
            r#"<integrator type="path"><integer name="max_depth" value="2"/></integrator>"#,
            &format!(r#"<integrator type="{integrator}"/>"#),
        );
        let mut desc =
            Scene::description_from_xml_str(&xml, &repo_path("tests/inline.xml"), &[]).unwrap();
        desc.mode = Mode::Spectral;
        Job::build(&desc).map(|_| ()).map_err(|e| e.to_string())
    };
    for ok in ["path", "direct", "volpath", "volpathmis", "ptracer", "bdpt"] {
        build(ok).unwrap_or_else(|e| panic!("{ok}: {e}"));
    }
    for refused in ["sppm", "whitted"] {
        match build(refused) {
            Err(e) => assert!(
                e.contains(&format!("{refused} renders in RGB mode only")) && !e.contains('\n'),
                "{refused}: {e}"
            ),
            Ok(()) => panic!("{refused} builds in spectral mode"),
        }
    }
}

/// Planck's law at `t` kelvins, W m⁻² sr⁻¹ nm⁻¹, `w` in nm (f64, CODATA 2014 as Mitsuba).
fn planck(w: f64, t: f64) -> f64 {
    let (h, c, k) = (6.62607004e-34f64, 2.99792458e8f64, 1.38064852e-23f64);
    let l = w * 1e-9;
    2.0 * h * c * c / (l.powi(5) * ((h * c / (l * k * t)).exp() - 1.0)) * 1e-9
}

/// A black-body environment: the furnace reflects ρ(λ) B(λ, 5000 K). RGB mode refuses the
/// scene in one line, as Mitsuba's RGB variants do.
#[test]
fn spectral_furnace_under_a_black_body() {
    let xml = furnace_xml(1.0).replace(
        r#"<spectrum name="radiance" value="1"/>"#,
        r#"<spectrum type="blackbody" name="radiance"><float name="temperature" value="5000"/></spectrum>"#,
    );
    assert!(xml.contains("blackbody"));
    let (mean, se) = render_mean(&xml, 256);
    check(
        "black-body furnace",
        mean,
        se,
        expected_rgb(|w| at(RHO, w) * planck(w, 5000.0)),
    );
    let desc = Scene::description_from_xml_str(&xml, &repo_path("tests/inline.xml"), &[]).unwrap();
    let e = Job::build(&desc).map(|_| ()).unwrap_err().to_string();
    assert!(
        e.contains("blackbody spectrum") && e.contains("spectral mode only") && !e.contains('\n'),
        "{e}"
    );
}

/// `aov` in spectral mode: the nested image and the albedo are spectra converted as camera
/// paths are (Mitsuba's aov divides the albedo by the wavelengths' pdf and converts it); the
/// depth is a number, bit for bit the RGB mode's. Each pixel of the sphere is an independent
/// estimate of the same value, so the standard error comes from the pixels' spread.
#[test]
fn aov_converts_its_spectra_and_keeps_its_numbers() {
    use penumbra::integrator::Integrator;
    use penumbra::render::render_channels;
    let l = 0.8;
    let xml = furnace_xml(l).replace(
        r#"<integrator type="path"><integer name="max_depth" value="2"/></integrator>"#,
        r#"<integrator type="aov"><string name="aovs" value="dd:depth,al:albedo"/>
            <integrator type="path" name="img"><integer name="max_depth" value="2"/></integrator>
        </integrator>"#,
    );
    let channels = |mode: Mode| {
        let mut desc =
            Scene::description_from_xml_str(&xml, &repo_path("tests/inline.xml"), &[]).unwrap();
        desc.mode = mode;
        let job = Job::build(&desc).unwrap();
        let Integrator::Aov(aov) = &job.integrator else {
            panic!("aov")
        };
        render_channels(&job.scene, aov, 64, 3, None).unwrap().0
    };
    let spectral = channels(Mode::Spectral);
    let rgb = channels(Mode::Rgb);
    let get = |ch: &[(String, Vec<f32>)], name: &str| {
        ch.iter().find(|(n, _)| n == name).unwrap().1.clone()
    };
    assert_eq!(get(&spectral, "dd.T"), get(&rgb, "dd.T"), "depth");
    let mean_se = |prefix: &str| {
        let per = |c: &str| {
            let v = get(&spectral, &format!("{prefix}.{c}"));
            let n = v.len() as f64;
            let m = v.iter().map(|&x| x as f64).sum::<f64>() / n;
            let var = v.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / (n - 1.0);
            (m, (var / n).sqrt())
        };
        let (r, g, b) = (per("R"), per("G"), per("B"));
        ([r.0, g.0, b.0], [r.1, g.1, b.1])
    };
    let (mean, se) = mean_se("al");
    check("aov albedo", mean, se, expected_rgb(|w| at(RHO, w)));
    let (mean, se) = mean_se("img");
    check(
        "aov nested path",
        mean,
        se,
        expected_rgb(|w| at(RHO, w) * l),
    );
}
