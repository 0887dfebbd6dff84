//! Analytic furnace tests: a camera inside a closed diffuse sphere whose inner surface has
//! albedo a and emits Le. Every camera ray sees L = Le Σ_{k<n} a^k for max_depth n (Mitsuba's
//! depth semantics: n = 1 is emission only), Le / (1 − a) unbounded.

mod common;
use common::*;

fn furnace_xml(albedo: f64, le: f64, max_depth: i64, shape: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="{max_depth}"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="70"/>
        <transform name="to_world"><lookat origin="0.1,0.2,0.05" target="1,0.5,-2" up="0,1,0"/></transform>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="16"/><rfilter type="box"/></film>
    </sensor>
    {shape}
        <boolean name="flip_normals" value="true"/>
        <bsdf type="diffuse"><float name="reflectance" value="{albedo}"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="{le}, {le2}, {le3}"/></emitter>
    </shape>
</scene>"#,
        le2 = le * 0.5,
        le3 = le * 2.0,
    )
}

const SPHERE: &str = r#"<shape type="sphere"><float name="radius" value="1.5"/>"#;
const CUBE: &str =
    r#"<shape type="cube"><transform name="to_world"><scale value="1.3"/></transform>"#;

/// Renders and checks the image mean against `expected` per channel: within 1% and within
/// 4.5 standard errors (|z| < 4.5 ↔ two-sided p < 7e-6 per check), plus a 1e-5 relative
/// allowance for f32 rounding of the per-path arithmetic (a few dozen operations of relative
/// error 6e-8 each): in a sphere furnace, NEE estimates are constant and the standard error
/// can be ~1e-8.
fn check(xml: &str, expected: [f64; 3], spp: u32) {
    let scene = scene_from_str(xml);
    let out = render_scene(&scene, spp, 7, None);
    assert_eq!(out.stats.nonfinite, 0);
    let (mean, se) = image_mean_and_se(&out, spp);
    for c in 0..3 {
        let err = (mean[c] - expected[c]).abs();
        assert!(
            err <= 0.01 * expected[c] && err <= 4.5 * se[c] + 1e-5 * expected[c],
            "channel {c}: mean {} expected {} (se {})",
            mean[c],
            expected[c],
            se[c]
        );
    }
}

#[test]
fn sphere_furnace_unbounded_depth_converges_to_le_over_one_minus_a() {
    let a = 0.8;
    let xml = furnace_xml(a, 1.0, -1, SPHERE);
    check(&xml, [1.0, 0.5, 2.0].map(|le| le / (1.0 - a)), 256);
}

#[test]
fn cube_furnace_unbounded_depth() {
    let a = 0.5;
    let xml = furnace_xml(a, 1.0, -1, CUBE);
    check(&xml, [1.0, 0.5, 2.0].map(|le| le / (1.0 - a)), 128);
}

#[test]
fn max_depth_truncates_the_neumann_series_exactly_as_mitsuba() {
    let a = 0.6;
    for n in [1i64, 2, 3, 6] {
        let xml = furnace_xml(a, 1.0, n, SPHERE);
        let series: f64 = (0..n).map(|k| a.powi(k as i32)).sum();
        check(&xml, [1.0, 0.5, 2.0].map(|le| le * series), 64);
    }
}

#[test]
fn emission_only_is_exact_at_every_pixel() {
    // max_depth 1: every sample returns Le exactly, so the f64 film gives Le bit for bit.
    let xml = furnace_xml(0.5, 3.0, 1, SPHERE);
    let scene = scene_from_str(&xml);
    let out = render_scene(&scene, 16, 1, None);
    for p in out.film.image() {
        assert_eq!(p, [3.0, 1.5, 6.0]);
    }
}

#[test]
fn max_depth_zero_renders_black() {
    let scene = scene_from_str(&furnace_xml(0.5, 1.0, 0, SPHERE));
    let out = render_scene(&scene, 2, 1, None);
    assert!(out.film.image().iter().all(|p| *p == [0.0; 3]));
}

/// The scene of the `hide_emitters` tests, seen by a 9 × 9 camera at z = 5 looking down:
/// `lights` small black (reflectance 0) emitting squares (half-size 0.2, Le = 5, facing the
/// camera) stacked 1e-3 apart from z = 1, in front of a diffuse wall (ρ = 0.5, z = 0) lit
/// only by a large emitter behind the camera (Le = 1, z = 6, facing the wall).
fn hidden_lights_scene(integrator: &str, hide: bool, lights: usize) -> String {
    let mut stack = String::new();
    for k in 0..lights {
        stack += &format!(
            r#"<shape type="rectangle"><transform name="to_world"><scale value="0.2"/><translate z="{}"/></transform>
        <bsdf type="diffuse"><float name="reflectance" value="0"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>
"#,
            1.0 + 1e-3 * k as f64
        );
    }
    format!(
        r#"<scene version="3.0.0">
    <integrator {integrator}<boolean name="hide_emitters" value="{hide}"/></integrator>
    <sensor type="perspective"><float name="fov" value="20"/>
        <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
        <film type="hdrfilm"><integer name="width" value="9"/><integer name="height" value="9"/><rfilter type="box"/></film></sensor>
    {stack}
    <shape type="rectangle"><transform name="to_world"><scale value="100"/></transform>
        <bsdf type="diffuse"><float name="reflectance" value="0.5"/></bsdf></shape>
    <shape type="rectangle"><transform name="to_world"><scale value="100"/><rotate x="1" angle="180"/><translate z="6"/></transform>
        <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
</scene>"#
    )
}

/// `hide_emitters` (Mitsuba 3.9.1 semantics): camera rays pass through directly visible area
/// emitters without using up a bounce. A camera looks at an emitting rectangle (Le = 5, facing
/// the camera) in front of a diffuse wall lit only by a second, large emitter behind the
/// camera (Le = 1, facing the wall); the front emitter is black (reflectance 0), so seen
/// directly it is exactly 5. With max_depth 2, a pixel through the front emitter sees
/// 5 normally, and the wall's direct lighting when the emitters are hidden, as do the pixels
/// beside the front emitter (which see the wall in both cases).
#[test]
fn hide_emitters_passes_camera_rays_through_area_lights() {
    // direct, whitted, volpath and volpathmis share the pass-through
    // (integrator::pass_through_emitters); path passes through in its own loop
    for integrator in [
        r#"type="path"><integer name="max_depth" value="2"/>"#,
        r#"type="direct">"#,
        r#"type="whitted"><integer name="max_depth" value="2"/>"#,
        r#"type="volpath"><integer name="max_depth" value="2"/>"#,
        r#"type="volpathmis"><integer name="max_depth" value="2"/>"#,
    ] {
        let xml = |hide: bool| hidden_lights_scene(integrator, hide, 1);
        // 4096 spp: a standard error of ~0.5% of the centre pixel, so a 3% error is ~6 se
        let spp = 4096;
        let shown = render_scene(&scene_from_str(&xml(false)), spp, 1, None)
            .film
            .image();
        let hidden_out = render_scene(&scene_from_str(&xml(true)), spp, 1, None);
        let hidden = hidden_out.film.image();
        let centre = 4 * 9 + 4;
        assert_eq!(shown[centre], [5.0; 3], "the emitter seen directly");
        // Hidden, the centre sees the wall behind with its direct light: radiance ρ L (F_big −
        // F_front), the point-to-parallel-square form factors of the big emitter (half-size 100
        // at height 6) and of the front rectangle that shadows it (half-size 0.2 at height 1),
        // averaged over the pixel's footprint on the wall. Had the pass-through used up a bounce,
        // max_depth 2 would leave no NEE at the wall: exactly 0.
        let half = 5.0 * (10.0f64).to_radians().tan() / 9.0;
        let n = 16;
        let mut expected = 0.0;
        for i in 0..n {
            for j in 0..n {
                let x = -half + (i as f64 + 0.5) / n as f64 * 2.0 * half;
                let y = -half + (j as f64 + 0.5) / n as f64 * 2.0 * half;
                expected += 0.5
                    * (parallel_square_form_factor(x, y, 100.0, 6.0)
                        - parallel_square_form_factor(x, y, 0.2, 1.0));
            }
        }
        expected /= (n * n) as f64;
        let var = hidden_out.film.sample_variance()[centre];
        for c in 0..3 {
            let z = (hidden[centre][c] as f64 - expected) / (var[c] as f64 / spp as f64).sqrt();
            assert!(
                z.abs() < 4.0,
                "{integrator} channel {c}: {} vs {expected:.5}, z = {z:.2}",
                hidden[centre][c]
            );
        }
        // Pixels that do not see the front emitter trace the same paths either way.
        assert_eq!(shown[0], hidden[0]);
        assert_eq!(shown[8 * 9 + 8], hidden[8 * 9 + 8]);
    }
}

/// In `direct`, `whitted`, `volpath` and `volpathmis`, a hidden camera ray passes through at
/// most 256 stacked area
/// lights (the documented limit of `integrator::pass_through_emitters`, which keeps a
/// pathological stack from costing unbounded rays): behind 200 of them it still reaches the
/// lit wall, behind 300 the pixel is black. The lights are small, black (reflectance 0)
/// squares 1e-3 apart in front of the wall; the wall is lit by a large emitter behind the
/// camera. (`path` passes through any number: its own loop, without a limit.)
#[test]
fn hide_emitters_gives_up_after_256_stacked_lights() {
    for integrator in [
        r#"type="direct">"#,
        r#"type="whitted"><integer name="max_depth" value="2"/>"#,
        r#"type="volpath"><integer name="max_depth" value="2"/>"#,
        r#"type="volpathmis"><integer name="max_depth" value="2"/>"#,
    ] {
        let stack = |count: usize| {
            let xml = hidden_lights_scene(integrator, true, count);
            render_scene(&scene_from_str(&xml), 16, 1, None)
                .film
                .image()[4 * 9 + 4]
        };
        // Behind the stack the wall is lit (direct light ~0.44, see the test above): a sample
        // that reaches it is 0 only if none of its rays towards the lights reaches the big one
        // (a cosine-distributed ray misses it or meets the stack with probability ~0.13), so
        // all 16 samples of the pixel are 0 with probability below 1e-14. Giving up is 0
        // exactly.
        let through = stack(200);
        assert!(
            through.iter().all(|&v| v > 0.0),
            "{integrator} 200 lights: {through:?}"
        );
        assert_eq!(stack(300), [0.0; 3], "{integrator} 300 lights");
    }
}

/// The form factor from a point at (x, y, 0), facing +z, to the square [−a, a]² at height
/// h facing it: the sum of the corner-rectangle form factors (Howell's catalogue, C-11:
/// (1/2π) [X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))], X, Y the rectangle's
/// sides over h), signed for the corners the point lies outside of.
fn parallel_square_form_factor(x: f64, y: f64, a: f64, h: f64) -> f64 {
    let corner = |u: f64, v: f64| {
        let (s, t) = (u.signum() * v.signum(), (u.abs() / h, v.abs() / h));
        let (p, q) = t;
        let f = (p / (1.0 + p * p).sqrt() * (q / (1.0 + p * p).sqrt()).atan()
            + q / (1.0 + q * q).sqrt() * (p / (1.0 + q * q).sqrt()).atan())
            / (2.0 * std::f64::consts::PI);
        s * f
    };
    // the rectangle [x0, x1] × [y0, y1] relative to the point, by inclusion-exclusion of
    // rectangles with a corner above the point
    let (x0, x1, y0, y1) = (-a - x, a - x, -a - y, a - y);
    corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)
}
