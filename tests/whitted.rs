//! `whitted`: direct light from a point light against the analytic value, depth semantics,
//! no randomness given the camera ray with delta lights and plain BSDFs, Fresnel-weighted
//! splitting at glass, and one-line errors. Agreement with Mitsuba's path tracer where
//! Whitted ray tracing is exact is checked by the validation entry `whitted-exact-whitted`
//! (tests/validation.rs). Also the `direct` integrator's ray and bounce counters.

mod common;
use common::*;
use glam::{Vec2, Vec3};
use penumbra::integrator::PathStats;
use penumbra::render::Job;
use penumbra::sampler::SampleStream;
use penumbra::scene::Scene;
use penumbra::spectrum::Spectrum;

/// A diffuse plane (reflectance 0.5) at y = 0 under a point light of intensity 4 at
/// (0.3, 2, -0.2), seen from (0, 4, 3).
fn plane_scene(max_depth: u32, extra: &str) -> Job {
    scene_from_str(&plane_xml(max_depth, extra))
}

fn plane_xml(max_depth: u32, extra: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
            <integrator type="whitted"><integer name="max_depth" value="{max_depth}"/></integrator>
            <sensor type="perspective">
                <float name="fov" value="50"/>
                <transform name="to_world"><lookat origin="0, 4, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
            </sensor>
            <shape type="rectangle">
                <transform name="to_world"><scale value="10"/><rotate x="1" angle="-90"/></transform>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
            </shape>
            <emitter type="point">
                <point name="position" x="0.3" y="2" z="-0.2"/>
                <rgb name="intensity" value="4"/>
            </emitter>
            {extra}
        </scene>"#
    )
}

fn li(scene: &Job, pixel: Vec2, stream: u64) -> Spectrum {
    let ray = scene.scene.camera.generate_ray(pixel / 16.0);
    let mut sampler = SampleStream::new(stream, 7, 0);
    scene.integrator.li(
        &scene.scene,
        ray,
        penumbra::spectrum::NO_WAVELENGTHS,
        &mut sampler,
        &mut PathStats::default(),
    )
}

/// The plane's direct light from the point light at the camera-relative point `p`:
/// (ρ/π) I cos θ / r². (The scene is built around the camera: the light sits at its
/// position minus the camera's.)
fn analytic_direct(p: Vec3) -> f32 {
    let to_light = Vec3::new(0.3, 2.0, -0.2) - Vec3::new(0.0, 4.0, 3.0) - p;
    0.5 / std::f32::consts::PI * 4.0 * to_light.normalize().y / to_light.length_squared()
}

/// Asserts that `got` is `expected` in every channel to 1e-4 relative.
fn assert_close(got: Spectrum, expected: f32, what: &str) {
    assert!(
        ((got - Spectrum::splat(expected)) / expected)
            .abs()
            .max_element()
            < 1e-4,
        "{what}: {got} against {expected}"
    );
}

#[test]
fn direct_light_of_a_point_light_is_the_analytic_value() {
    let scene = plane_scene(2, "");
    let mut checked = 0;
    for y in 0..16 {
        for x in 0..16 {
            let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let ray = scene.scene.camera.generate_ray(pixel / 16.0);
            let Some(si) = scene.scene.intersect(&ray) else {
                continue;
            };
            let got = li(&scene, pixel, 0);
            assert_close(got, analytic_direct(si.p), &format!("pixel ({x}, {y})"));
            checked += 1;
        }
    }
    assert!(checked > 200, "the plane fills the view: {checked} pixels");
    // max_depth 1: emitters seen directly only, and a point light cannot be seen.
    let scene = plane_scene(1, "");
    assert_eq!(li(&scene, Vec2::splat(8.0), 0), Spectrum::ZERO);
}

/// `shadows` false (the ladder's "ray casting only"): a panel between the light and the
/// plane casts no shadow, and every pixel keeps the analytic unoccluded value; with shadow
/// rays the pixels behind it are black.
#[test]
fn without_shadows_an_occluder_casts_no_shadow() {
    // A panel at y = 1 under the light (light at y = 2, plane at y = 0): its shadow on the
    // plane is about 0.6 wide around (0.3, 0, −0.2).
    let panel = r#"<shape type="rectangle">
            <transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/>
                <translate x="0.3" y="1" z="-0.2"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
        </shape>"#;
    let depth = r#"<integer name="max_depth" value="2"/>"#;
    let xml = plane_xml(2, panel);
    let no_shadows = scene_from_str(&xml.replace(
        depth,
        &format!(r#"{depth}<boolean name="shadows" value="false"/>"#),
    ));
    let shadows = scene_from_str(&xml);
    let (mut shadowed, mut checked) = (0, 0);
    for y in 0..16 {
        for x in 0..16 {
            let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let ray = shadows.scene.camera.generate_ray(pixel / 16.0);
            let Some(si) = shadows.scene.intersect(&ray) else {
                continue;
            };
            if si.p.y > -3.5 {
                continue; // the panel itself (the plane is at y = -4 camera-relative)
            }
            let got = li(&no_shadows, pixel, 0);
            assert_close(
                got,
                analytic_direct(si.p),
                &format!("pixel ({x}, {y}) without shadows"),
            );
            checked += 1;
            if li(&shadows, pixel, 0) == Spectrum::ZERO {
                shadowed += 1;
            }
        }
    }
    assert!(checked > 150, "{checked} plane pixels");
    assert!(
        shadowed >= 2,
        "the panel shadows {shadowed} pixels with shadow rays"
    );
}

/// The counters a render reports (rays, bounces): a camera ray that hits the plane at
/// max_depth 2 is one bounce and two rays (its own and the shadow ray to the point light).
#[test]
fn rays_and_bounces_are_counted() {
    let (l, stats) = centre_pixel_with_stats(&plane_scene(2, ""));
    assert!(l.max_element() > 0.0);
    assert_eq!((stats.rays, stats.bounces), (2, 1));
}

/// The radiance of the image centre's camera ray and the counters of computing it.
fn centre_pixel_with_stats(scene: &Job) -> (Spectrum, PathStats) {
    let ray = scene.scene.camera.generate_ray(Vec2::splat(0.5));
    let mut stats = PathStats::default();
    let mut sampler = SampleStream::new(0, 7, 0);
    let l = scene.integrator.li(
        &scene.scene,
        ray,
        penumbra::spectrum::NO_WAVELENGTHS,
        &mut sampler,
        &mut stats,
    );
    (l, stats)
}

/// The same counters for Mitsuba's `direct` integrator on the plane: a camera ray that hits
/// it is one bounce; its rays are the camera ray, the shadow ray to the point light and the
/// BSDF sample's ray (one emitter and one BSDF sample by default).
#[test]
fn direct_counts_rays_and_bounces() {
    let xml = plane_xml(2, "").replace(
        r#"<integrator type="whitted"><integer name="max_depth" value="2"/></integrator>"#,
        r#"<integrator type="direct"/>"#,
    );
    let (l, stats) = centre_pixel_with_stats(&scene_from_str(&xml));
    assert!(l.max_element() > 0.0);
    assert_eq!((stats.rays, stats.bounces), (3, 1));
}

/// The same counters for the path tracers (path, volpath, volpathmis), under a ceiling
/// that catches every bounce off the plane (a 2 km square 6 m up: an upward ray misses it
/// only within 6e-3 rad of the horizon, probability 4e-5 for a cosine-weighted bounce): at
/// max_depth 3 a camera path hits the plane and the ceiling (two bounces) and traces five
/// rays: the camera ray, a shadow ray and a continuation from each of the two surfaces (the
/// second continuation reaches the plane at the last depth and stops there).
#[test]
fn path_counts_rays_and_bounces() {
    let ceiling = r#"<shape type="rectangle">
            <transform name="to_world"><scale value="1000"/><rotate x="1" angle="90"/><translate y="6"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
        </shape>"#;
    for integrator in ["path", "volpath", "volpathmis"] {
        let xml =
            plane_xml(3, ceiling).replace(r#"type="whitted""#, &format!(r#"type="{integrator}""#));
        let (l, stats) = centre_pixel_with_stats(&scene_from_str(&xml));
        assert!(l.max_element() > 0.0, "{integrator}");
        assert_eq!((stats.rays, stats.bounces), (5, 2), "{integrator}");
    }
}

#[test]
fn no_randomness_given_the_camera_ray() {
    // Point and spot lights, a mirror, glass and a thin panel: every branch is followed, so
    // the sampler's numbers do not matter.
    let scene = load(
        "scenes/whitted-exact.xml",
        &[("integrator", "whitted"), ("res", "16"), ("max_depth", "6")],
    );
    let mut nonzero = 0;
    for y in 0..16 {
        for x in 0..16 {
            let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let a = li(&scene, pixel, 1);
            assert_eq!(a, li(&scene, pixel, 2), "pixel ({x}, {y})");
            nonzero += (a != Spectrum::ZERO) as u32;
        }
    }
    assert!(nonzero > 100, "{nonzero}");
}

#[test]
fn glass_splits_into_fresnel_weighted_reflection_and_refraction() {
    // A glass sheet just above the plane reflects a small area light: a pixel whose
    // reflected ray meets the light is F(cos θ) · 10 exactly: the refracted branch (1 − F)
    // reaches the plane, where every shadow ray is blocked by the sheet.
    let emitter = r#"<shape type="rectangle">
            <transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate x="0" y="3" z="-3"/></transform>
            <emitter type="area"><rgb name="radiance" value="10"/></emitter>
        </shape>"#;
    let glass = r#"<shape type="rectangle">
            <transform name="to_world"><scale value="10"/><rotate x="1" angle="-90"/><translate y="0.01"/></transform>
            <bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf>
        </shape>"#;
    let with_glass = plane_scene(3, &format!("{emitter}{glass}"));
    // Find a pixel whose ray reflects off the glass into the area light.
    let mut found = 0;
    for y in 0..16 {
        for x in 0..16 {
            let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let ray = with_glass.scene.camera.generate_ray(pixel / 16.0);
            let Some(si) = with_glass.scene.intersect(&ray) else {
                continue;
            };
            let d = ray.d.normalize();
            let reflected = Vec3::new(d.x, -d.y, d.z);
            let next = Scene::spawn_ray(&si, reflected);
            let Some(hit) = with_glass.scene.intersect(&next) else {
                continue;
            };
            if with_glass.scene.shapes[hit.shape as usize]
                .emitter
                .is_none()
            {
                continue;
            }
            // Light under the glass is blocked by it (its shadow rays hit the glass), so
            // the pixel is the reflected emitter: F(cos θ) · 10.
            let cos = -d.y;
            // Mitsuba's default ext_ior is air's, 1.000277
            let f = fresnel_reflectance(cos as f64, 1.000277, 1.5) as f32;
            let got = li(&with_glass, pixel, 0);
            let expected = f * 10.0;
            assert!(
                ((got - Spectrum::splat(expected)) / expected)
                    .abs()
                    .max_element()
                    < 1e-5,
                "pixel ({x}, {y}): {got} against F = {f} x 10"
            );
            found += 1;
        }
    }
    assert!(found > 0, "no pixel sees the light in the glass");
}

#[test]
fn bad_parameters_are_one_line_errors() {
    for (xml, expect) in [
        (r#"<integer name="max_depth" value="0"/>"#, "max_depth"),
        (r#"<integer name="max_depth" value="21"/>"#, "max_depth"),
        (
            r#"<integer name="emitter_samples" value="0"/>"#,
            "emitter_samples",
        ),
        (r#"<integer name="rr_depth" value="3"/>"#, "rr_depth"),
    ] {
        let doc = format!(
            r#"<scene version="3.0.0"><integrator type="whitted">{xml}</integrator>
               <sensor type="perspective"/></scene>"#
        );
        let err = Job::from_xml_str(&doc, &repo_path("tests/inline.xml"), &[])
            .err()
            .unwrap_or_else(|| panic!("{xml} was accepted"))
            .to_string();
        assert!(err.contains(expect) && !err.contains('\n'), "{err}");
    }
}
