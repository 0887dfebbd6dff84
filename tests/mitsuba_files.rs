//! Mitsuba's scene files as Mitsuba reads them: the example scenes load unchanged, spectra
//! become the RGB of Mitsuba's RGB variants in each role, a light without a BSDF is black,
//! shapes carry Mitsuba's parameterisation (uv, dp/du, the shading frame's tangent) and the
//! `direct`, `moment`, `shapegroup`/`instance`, `orthographic` and default-sensor constructs
//! parse with Mitsuba's defaults.

mod common;

use common::repo_path;
use glam::{DVec3, Vec3};
use penumbra::geometry::Ray;
use penumbra::scene::description::{
    from_xml, BsdfDesc, EmitterDesc, IntegratorDesc, SceneDescription, ShapeKind,
};
use penumbra::scene::xml::load_str;
use penumbra::scene::Scene;
use std::path::Path;

const FILE: &str = "/virtual/dir/scene.xml";

const SENSOR: &str = r#"<sensor type="perspective">
    <float name="fov" value="45"/>
    <film type="hdrfilm">
        <integer name="width" value="32"/>
        <integer name="height" value="24"/>
        <rfilter type="box"/>
    </film>
</sensor>"#;

fn parse(body: &str) -> penumbra::Result<SceneDescription> {
    let xml = format!("<scene version=\"3.0.0\">\n{SENSOR}\n{body}\n</scene>\n");
    from_xml(&load_str(&xml, Path::new(FILE), &[])?)
}

fn desc(body: &str) -> SceneDescription {
    parse(body).unwrap_or_else(|e| panic!("expected a valid scene, got: {e}\n{body}"))
}

fn error(body: &str) -> String {
    match parse(body) {
        Ok(d) => panic!("expected an error, got {d:?}"),
        Err(e) => e.to_string(),
    }
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).abs().max_element() <= tol
}

/// Mitsuba's example scenes load unchanged (and build): the spectral Cornell box, the RGB one
/// with its forward reference, the spectral fragments, and hello.xml with `<path>`, a PLY and
/// the direct integrator.
#[test]
fn mitsubas_example_scenes_load() {
    for file in [
        "scenes/mitsuba/cbox/cbox.xml",
        "scenes/mitsuba/cbox/cbox-rgb.xml",
        "scenes/mitsuba/cbox/cbox-spectral.xml",
        "scenes/mitsuba/hello.xml",
    ] {
        let scene = Scene::load(&repo_path(file), &[]).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(!scene.emitters.is_empty(), "{file}");
        assert!(scene.accel.primitive_count() > 0, "{file}");
    }
    let cbox = Scene::load_description(&repo_path("scenes/mitsuba/cbox/cbox.xml"), &[]).unwrap();
    assert_eq!(cbox.shapes.len(), 8);
    // The luminaire's reflectance (a flat 0.78 spectrum, D65-weighted) is the grey Mitsuba
    // stores, and its emission spectrum the colour Mitsuba stores for it (from
    // tests/data/mitsuba_spectrum_values.txt).
    match &cbox.shapes[0].bsdf {
        BsdfDesc::Diffuse { reflectance } => assert!(
            close(
                *reflectance,
                DVec3::new(0.77636677, 0.779810011, 0.77602911),
                1e-7
            ),
            "{reflectance}"
        ),
        other => panic!("{other:?}"),
    }
    match &cbox.shapes[0].emitter {
        Some(EmitterDesc::Area { radiance }) => assert!(
            close(
                *radiance,
                DVec3::new(20.7108364, 10.8546343, 2.77115202),
                1e-5
            ),
            "{radiance}"
        ),
        other => panic!("{other:?}"),
    }
    let rgb = Scene::load_description(&repo_path("scenes/mitsuba/cbox/cbox-rgb.xml"), &[]).unwrap();
    match &rgb.shapes[0].emitter {
        Some(EmitterDesc::Area { radiance }) => {
            assert_eq!(*radiance, DVec3::new(18.387, 10.9873, 2.75357))
        }
        other => panic!("{other:?}"),
    }
    assert!(
        rgb.emitters.is_empty(),
        "the scene-level area emitter only emits via the shape"
    );
    let hello = Scene::load_description(&repo_path("scenes/mitsuba/hello.xml"), &[]).unwrap();
    assert_eq!(
        hello.integrator,
        IntegratorDesc::Direct {
            emitter_samples: 4,
            bsdf_samples: 0,
            hide_emitters: false
        }
    );
    // No fov: Mitsuba's 50 mm focal length on a 36x24 mm film, as a diagonal field of view.
    let diag = 2.0 * (43.266615305567875f64 / 100.0).atan().to_degrees();
    assert!(
        (hello.sensor.fov - diag).abs() < 1e-9,
        "{}",
        hello.sensor.fov
    );
}

/// A `<spectrum>` becomes RGB by the role of the parameter that reads it: reflectances are
/// D65-weighted and clamped, conductor IORs unbounded, emission not D65-weighted, and a
/// uniform spectrum on an emitter is not grey (Mitsuba's RGB variants imitate the spectral
/// ones). The values are Mitsuba's (tests/data/mitsuba_spectrum_values.txt).
#[test]
fn spectra_take_the_role_of_their_parameter() {
    let d = desc(
        r#"<shape type="sphere">
             <bsdf type="conductor">
               <spectrum name="eta" value="0.789"/>
               <spectrum name="k" value="400:1, 700:7"/>
             </bsdf>
             <emitter type="area"><spectrum name="radiance" value="0.5"/></emitter>
           </shape>
           <shape type="sphere">
             <bsdf type="diffuse"><spectrum name="reflectance" value="400:2, 700:2"/></bsdf>
           </shape>"#,
    );
    match &d.shapes[0].bsdf {
        BsdfDesc::Conductor { eta, k, .. } => {
            assert!(close(*eta, DVec3::splat(0.789), 1e-7), "{eta}");
            assert!(k.z < k.x && k.x > 1.0, "unbounded, not clamped: {k}");
        }
        other => panic!("{other:?}"),
    }
    match &d.shapes[0].emitter {
        Some(EmitterDesc::Area { radiance }) => {
            // 0.5 · xyz_to_srgb(1, 1, 1), the f32 values Mitsuba stores.
            assert!(
                close(
                    *radiance,
                    DVec3::new(0.602396965, 0.474145502, 0.454458028),
                    1e-7
                ),
                "{radiance}"
            );
        }
        other => panic!("{other:?}"),
    }
    match &d.shapes[1].bsdf {
        BsdfDesc::Diffuse { reflectance } => {
            assert!(
                close(*reflectance, DVec3::ONE, 0.0),
                "clamped to 1: {reflectance}"
            )
        }
        other => panic!("{other:?}"),
    }
    assert!(
        d.warnings.iter().any(|w| w.contains("clamping")),
        "{:?}",
        d.warnings
    );
    // <rgb> reflectances outside [0, 1] are refused, as Mitsuba's srgb texture does; the
    // same on an emitter is fine.
    let e = error(
        r#"<shape type="sphere"><bsdf type="diffuse"><rgb name="reflectance" value="1.5, 0.2, 0.2"/></bsdf></shape>"#,
    );
    assert!(
        e.contains("invalid RGB reflectance") && e.contains("scene.xml:10:"),
        "{e}"
    );
    desc(
        r#"<shape type="sphere"><emitter type="area"><rgb name="radiance" value="15"/></emitter></shape>"#,
    );
    let e = error(
        r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="500:1, 400:1"/></bsdf></shape>"#,
    );
    assert!(e.contains("<spectrum name=\"reflectance\">"), "{e}");
}

/// Mitsuba gives a shape with an emitter but no BSDF a black diffuse BSDF; other shapes
/// without a BSDF get diffuse 0.5.
#[test]
fn a_light_without_a_bsdf_is_black() {
    let d = desc(
        r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
           <shape type="rectangle"/>"#,
    );
    assert_eq!(
        d.shapes[0].bsdf,
        BsdfDesc::Diffuse {
            reflectance: DVec3::ZERO
        }
    );
    assert_eq!(
        d.shapes[1].bsdf,
        BsdfDesc::Diffuse {
            reflectance: DVec3::splat(0.5)
        }
    );
}

#[test]
fn direct_and_moment_integrators() {
    let d = desc(r#"<integrator type="direct"/>"#);
    assert_eq!(
        d.integrator,
        IntegratorDesc::Direct {
            emitter_samples: 1,
            bsdf_samples: 1,
            hide_emitters: false
        }
    );
    assert!(!d.moment);
    let d = desc(
        r#"<integrator type="moment"><integrator type="direct"><integer name="shading_samples" value="3"/></integrator></integrator>"#,
    );
    assert!(d.moment);
    assert_eq!(
        d.integrator,
        IntegratorDesc::Direct {
            emitter_samples: 3,
            bsdf_samples: 3,
            hide_emitters: false
        }
    );
    let d = desc(
        r#"<integrator type="moment"><integrator type="path"><integer name="max_depth" value="2"/></integrator></integrator>"#,
    );
    assert!(d.moment && matches!(d.integrator, IntegratorDesc::Path { max_depth: 2, .. }));
    for (body, part) in [
        (
            r#"<integrator type="direct"><integer name="shading_samples" value="2"/><integer name="bsdf_samples" value="1"/></integrator>"#,
            "not both",
        ),
        (
            r#"<integrator type="direct"><integer name="emitter_samples" value="0"/><integer name="bsdf_samples" value="0"/></integrator>"#,
            "at least 1",
        ),
        (r#"<integrator type="moment"/>"#, "needs a nested"),
        (
            r#"<integrator type="moment"><integrator type="path"/><integrator type="direct"/></integrator>"#,
            "one nested integrator",
        ),
        (
            r#"<integrator type="volpath"/>"#,
            "unsupported plugin <integrator type=\"volpath\">",
        ),
    ] {
        let e = error(body);
        assert!(e.contains(part), "{body}: {e}");
    }
}

#[test]
fn sensors_with_mitsuba_defaults() {
    let d = from_xml(
        &load_str(
            r#"<scene version="3.0.0"><sensor type="perspective"><string name="focal_length" value="35mm"/></sensor></scene>"#,
            Path::new(FILE),
            &[],
        )
        .unwrap(),
    )
    .unwrap();
    let expected = 2.0
        * ((36.0f64 * 36.0 + 24.0 * 24.0).sqrt() / 70.0)
            .atan()
            .to_degrees();
    assert!((d.sensor.fov - expected).abs() < 1e-12);
    let d = from_xml(
        &load_str(
            r#"<scene version="3.0.0"><sensor type="orthographic"><float name="near_clip" value="1"/></sensor></scene>"#,
            Path::new(FILE),
            &[],
        )
        .unwrap(),
    )
    .unwrap();
    assert!(d.sensor.orthographic && d.sensor.near_clip == 1.0);
    let e = from_xml(
        &load_str(
            r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="30"/><string name="focal_length" value="20mm"/></sensor></scene>"#,
            Path::new(FILE),
            &[],
        )
        .unwrap(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("either a focal length"), "{e}");
}

#[test]
fn shape_groups_and_instances() {
    let d = desc(
        r#"<shape type="shapegroup" id="g">
             <shape type="sphere"/><shape type="rectangle"/>
           </shape>
           <shape type="instance"><ref id="g"/></shape>
           <shape type="instance"><ref id="g"/><transform name="to_world"><translate x="3"/></transform></shape>"#,
    );
    assert_eq!(d.shape_groups.len(), 1, "one group however many instances");
    assert_eq!(d.shape_groups[0].shapes.len(), 2);
    assert_eq!(d.shapes.len(), 2);
    assert!(d
        .shapes
        .iter()
        .all(|s| matches!(s.kind, ShapeKind::Instance { group: 0 })));
    for (body, part) in [
        (
            r#"<shape type="shapegroup" id="g"><shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape></shape>"#,
            "instancing of emitters",
        ),
        (
            r#"<shape type="instance"/>"#,
            "needs a <ref> to a shapegroup",
        ),
        (
            r#"<bsdf type="diffuse" id="b"/><shape type="instance"><ref id="b"/></shape>"#,
            "an instance takes one shapegroup",
        ),
        (
            r#"<shape type="sphere"><shape type="shapegroup"/></shape>"#,
            "cannot be nested",
        ),
    ] {
        let e = error(body);
        assert!(e.contains(part), "{body}: {e}");
    }
}

/// An instanced shape is hit where the same shape placed directly is, with the same normal:
/// rays through a transformed group against the transformed shape itself.
#[test]
fn instances_hit_like_the_shapes_they_place() {
    let t = r#"<transform name="to_world"><scale x="1.5" y="0.7" z="1"/><rotate x="1" angle="30"/><translate x="0.5" y="4" z="0.2"/></transform>"#;
    let base = |body: &str| {
        format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="60"/>
               <transform name="to_world"><lookat origin="0,0,0" target="0,1,0" up="0,0,1"/></transform></sensor>{body}</scene>"#
        )
    };
    let direct = Scene::from_xml_str(
        &base(&format!(r#"<shape type="cube">{t}</shape>"#)),
        Path::new(FILE),
        &[],
    )
    .unwrap();
    let instanced = Scene::from_xml_str(
        &base(&format!(
            r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape><shape type="instance"><ref id="g"/>{t}</shape>"#
        )),
        Path::new(FILE),
        &[],
    )
    .unwrap();
    let mut hits = 0;
    for i in 0..400 {
        let u = (i % 20) as f32 / 20.0 - 0.5;
        let v = (i / 20) as f32 / 20.0 - 0.5;
        let ray = Ray::new(
            Vec3::ZERO,
            Vec3::new(u * 1.5 + 0.5, 4.0, v * 1.5 + 0.2),
            f32::INFINITY,
        );
        let a = direct.intersect(&ray);
        let b = instanced.intersect(&ray);
        assert_eq!(a.is_some(), b.is_some(), "ray {i}");
        if let (Some(a), Some(b)) = (a, b) {
            hits += 1;
            assert!(
                (a.t - b.t).abs() <= 1e-5 * a.t,
                "ray {i}: {} vs {}",
                a.t,
                b.t
            );
            assert!(
                (a.ng - b.ng).length() < 1e-5,
                "ray {i}: {} vs {}",
                a.ng,
                b.ng
            );
            assert!((a.uv - b.uv).length() < 1e-4, "ray {i}");
            assert!((a.frame.s - b.frame.s).length() < 1e-4, "ray {i}");
            assert!((a.p - b.p).length() <= 1e-5 * a.p.length());
            // The error bound covers the difference between the two computations.
            let d = (a.p - b.p).abs();
            assert!(
                d.cmple(a.p_error + b.p_error).all(),
                "ray {i}: {d} vs {} + {}",
                a.p_error,
                b.p_error
            );
        }
    }
    assert!(hits > 150, "{hits}");
}

/// One line of tests/data/mitsuba_frames.txt: the ray and what Mitsuba found.
struct FrameRecord {
    name: String,
    d: Vec3,
    hit: Option<[f64; 18]>,
}

fn frame_records() -> Vec<FrameRecord> {
    let text = std::fs::read_to_string(repo_path("tests/data/mitsuba_frames.txt")).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (head, tail) = l.split_once('|').unwrap();
            let h: Vec<&str> = head.split_whitespace().collect();
            let d = Vec3::new(
                h[4].parse().unwrap(),
                h[5].parse().unwrap(),
                h[6].parse().unwrap(),
            );
            let hit = (tail.trim() != "miss").then(|| {
                let v: Vec<f64> = tail
                    .split_whitespace()
                    .map(|x| x.parse().unwrap())
                    .collect();
                <[f64; 18]>::try_from(v.as_slice()).unwrap()
            });
            FrameRecord {
                name: h[0].to_string(),
                d,
                hit,
            }
        })
        .collect()
}

/// uv, dp/du and the shading frame at ray hits on every shape kind, against Mitsuba 3.9.1's
/// (validation/mitsuba/frames.py on tests/data/frames.xml): the tangent of the shading frame
/// is dp/du made orthogonal to the shading normal, so anisotropic BSDFs line up.
#[test]
fn surface_frames_match_mitsuba() {
    let scene = Scene::load(&repo_path("tests/data/frames.xml"), &[]).unwrap();
    let records = frame_records();
    assert!(records.len() >= 90, "{}", records.len());
    let mut checked = 0;
    for r in &records {
        let ray = Ray::new(Vec3::ZERO, r.d, f32::INFINITY);
        let si = scene.intersect(&ray);
        let Some(m) = r.hit else {
            assert!(si.is_none(), "{}: Mitsuba misses, penumbra hits", r.name);
            continue;
        };
        let si = si.unwrap_or_else(|| panic!("{}: Mitsuba hits, penumbra misses", r.name));
        let v = |i: usize| DVec3::new(m[i], m[i + 1], m[i + 2]);
        let what = format!("{} d={}", r.name, r.d);
        assert!(
            (si.t as f64 - m[0]).abs() <= 2e-5 * m[0],
            "{what}: t {} vs {}",
            si.t,
            m[0]
        );
        assert!(
            close(si.p.as_dvec3(), v(1), 2e-5 * v(1).length()),
            "{what}: p {} vs {}",
            si.p,
            v(1)
        );
        assert!(
            close(si.ng.as_dvec3(), v(4), 1e-4),
            "{what}: ng {} vs {}",
            si.ng,
            v(4)
        );
        assert!(
            close(si.frame.n.as_dvec3(), v(7), 1e-4),
            "{what}: n {} vs {}",
            si.frame.n,
            v(7)
        );
        assert!(
            close(si.frame.s.as_dvec3(), v(10), 2e-4),
            "{what}: s {} vs {}",
            si.frame.s,
            v(10)
        );
        let uv = si.uv.as_dvec2();
        assert!(
            (uv.x - m[13]).abs() < 1e-4 && (uv.y - m[14]).abs() < 1e-4,
            "{what}: uv {uv} vs {} {}",
            m[13],
            m[14]
        );
        let dp = v(15);
        assert!(
            close(si.dp_du.as_dvec3(), dp, 2e-4 * dp.length().max(1.0)),
            "{what}: dp/du {} vs {dp}",
            si.dp_du
        );
        checked += 1;
    }
    assert!(checked >= 80, "{checked}");
}
