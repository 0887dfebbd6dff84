//! Mitsuba's scene files as Mitsuba reads them: its example scenes load unchanged (with the
//! RGB its RGB variants make of their spectra), instances hit like the shapes they place, and
//! every shape carries Mitsuba's parameterisation (uv, dp/du and the shading frame's tangent,
//! against values printed by Mitsuba). The plugin-level semantics (spectra by role, black
//! BSDFs on lights, `direct`, `moment`, default sensors, shape groups) are in description.rs.

mod common;

use common::{compare_instanced_hits, repo_path, HitChecks};
use glam::{DVec3, Vec3};
use penumbra::geometry::Ray;
use penumbra::render::Job;
use penumbra::scene::description::{EmitterDesc, IntegratorDesc};
use penumbra::scene::Scene;
use std::path::Path;

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
        let scene = Job::load(&repo_path(file), &[]).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(!scene.scene.emitters.is_empty(), "{file}");
        assert!(scene.scene.accel.primitive_count() > 0, "{file}");
    }
    let cbox = Scene::load_description(&repo_path("scenes/mitsuba/cbox/cbox.xml"), &[]).unwrap();
    assert_eq!(cbox.shapes.len(), 8);
    // The luminaire's reflectance (a flat 0.78 spectrum, D65-weighted) is the grey Mitsuba
    // stores, and its emission spectrum the colour Mitsuba stores for it (from
    // tests/data/mitsuba_spectrum_values.txt).
    match cbox.shapes[0].bsdf.param("reflectance") {
        Some(reflectance) => assert!(
            close(
                reflectance.constant_rgb().unwrap(),
                DVec3::new(0.77636677, 0.779810011, 0.77602911),
                1e-7
            ),
            "{reflectance:?}"
        ),
        other => panic!("{other:?}"),
    }
    match &cbox.shapes[0].emitter {
        Some(EmitterDesc::Area { radiance }) => assert!(
            radiance.constant_rgb().is_some_and(|c| close(
                c,
                DVec3::new(20.7108364, 10.8546343, 2.77115202),
                1e-5
            )),
            "{radiance:?}"
        ),
        other => panic!("{other:?}"),
    }
    let rgb = Scene::load_description(&repo_path("scenes/mitsuba/cbox/cbox-rgb.xml"), &[]).unwrap();
    match &rgb.shapes[0].emitter {
        Some(EmitterDesc::Area { radiance }) => {
            assert_eq!(
                radiance.constant_rgb(),
                Some(DVec3::new(18.387, 10.9873, 2.75357))
            )
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
    let direct = Job::from_xml_str(
        &base(&format!(r#"<shape type="cube">{t}</shape>"#)),
        Path::new("/virtual/dir/scene.xml"),
        &[],
    )
    .unwrap();
    let instanced = Job::from_xml_str(
        &base(&format!(
            r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape><shape type="instance"><ref id="g"/>{t}</shape>"#
        )),
        Path::new("/virtual/dir/scene.xml"),
        &[],
    )
    .unwrap();
    let rays = (0..400).map(|i| {
        let u = (i % 20) as f32 / 20.0 - 0.5;
        let v = (i / 20) as f32 / 20.0 - 0.5;
        Ray::new(
            Vec3::ZERO,
            Vec3::new(u * 1.5 + 0.5, 4.0, v * 1.5 + 0.2),
            f32::INFINITY,
        )
    });
    let checks = HitChecks {
        ng_tolerance: 1e-5,
        surface_details: true,
    };
    let hits = compare_instanced_hits(&direct.scene, &instanced.scene, rays, &checks, "cube");
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
    let scene = Job::load(&repo_path("tests/data/frames.xml"), &[]).unwrap();
    let records = frame_records();
    assert!(records.len() >= 90, "{}", records.len());
    let mut checked = 0;
    for r in &records {
        let ray = Ray::new(Vec3::ZERO, r.d, f32::INFINITY);
        let si = scene.scene.intersect(&ray);
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
