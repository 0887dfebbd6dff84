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
