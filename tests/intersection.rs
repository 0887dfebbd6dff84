//! Scene-level ray intersection: every shape type hit and missed, from inside and outside,
//! at grazing angles, the nearest hit chosen; and pbrt's re-intersection test: a ray spawned
//! from a hit never hits the surface it leaves, at any scale or distance from the origin.

mod common;
use common::*;
use glam::Vec3;
use penumbra::geometry::Ray;
use penumbra::render::Job;
use penumbra::scene::Scene;
use rand::RngExt;
use rand_pcg::Pcg32;

const SENSOR: &str = r#"<sensor type="perspective"><float name="fov" value="45"/>
    <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/><rfilter type="box"/></film></sensor>"#;

fn scene(shapes: &str) -> Job {
    scene_from_str(&format!(
        r#"<scene version="3.0.0">{SENSOR}{shapes}</scene>"#
    ))
}

fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
    Ray::new(Vec3::from(o), Vec3::from(d).normalize(), f32::INFINITY)
}

#[test]
fn rectangle_hits_misses_and_normal() {
    let s = scene(
        r#"<shape type="rectangle"><transform name="to_world"><scale x="2" y="1" z="1"/><translate z="-3"/></transform></shape>"#,
    );
    let si = s
        .scene
        .intersect(&ray([1.9, 0.9, 0.0], [0.0, 0.0, -1.0]))
        .unwrap();
    assert!((si.t - 3.0).abs() < 1e-6 && (si.ng - Vec3::Z).length() < 1e-6);
    assert!(s
        .scene
        .intersect(&ray([2.1, 0.0, 0.0], [0.0, 0.0, -1.0]))
        .is_none());
    assert!(s
        .scene
        .intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]))
        .is_none());
    // from behind: still hit (one-sidedness is the BSDF's business, not the geometry's)
    let si = s
        .scene
        .intersect(&ray([0.0, 0.0, -5.0], [0.0, 0.0, 1.0]))
        .unwrap();
    assert!((si.t - 2.0).abs() < 1e-6);
    // grazing
    let si = s
        .scene
        .intersect(&ray([-50.0, 0.5, -2.0], [50.0, 0.0, -1.0]))
        .unwrap();
    assert!((si.p.z + 3.0).abs() < 1e-4);
}

#[test]
fn cube_from_outside_and_inside() {
    let s = scene(
        r#"<shape type="cube"><transform name="to_world"><translate x="5"/></transform></shape>"#,
    );
    let si = s
        .scene
        .intersect(&ray([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]))
        .unwrap();
    assert!(
        (si.t - 4.0).abs() < 1e-6 && (si.ng + Vec3::X).length() < 1e-6,
        "outward normal"
    );
    let si = s
        .scene
        .intersect(&ray([5.0, 0.2, 0.3], [0.0, 1.0, 0.0]))
        .unwrap();
    assert!((si.t - 0.8).abs() < 1e-6 && (si.ng - Vec3::Y).length() < 1e-6);
    assert!(s
        .scene
        .intersect(&ray([0.0, 1.01, 0.0], [1.0, 0.0, 0.0]))
        .is_none());
    // through an edge of the cube (watertight: no slip between the faces)
    let si = s.scene.intersect(&ray([4.0, 1.0, 0.0], [1.0, -1.0, 0.0]));
    assert!(si.is_some());
}

#[test]
fn disk_hits_inside_radius_only() {
    let s = scene(
        r#"<shape type="disk"><transform name="to_world"><scale value="2"/><rotate x="1" angle="90"/></transform></shape>"#,
    );
    // rotated 90° about x: local +z becomes world -y
    let si = s
        .scene
        .intersect(&ray([1.9, 5.0, 0.0], [0.0, -1.0, 0.0]))
        .unwrap();
    assert!((si.t - 5.0).abs() < 1e-5 && (si.ng + Vec3::Y).length() < 1e-6);
    assert!(s
        .scene
        .intersect(&ray([1.5, 5.0, 1.5], [0.0, -1.0, 0.0]))
        .is_none());
}

#[test]
fn sphere_outside_inside_grazing() {
    let s = scene(
        r#"<shape type="sphere"><point name="center" x="0" y="0" z="-10"/><float name="radius" value="2"/></shape>"#,
    );
    let si = s
        .scene
        .intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]))
        .unwrap();
    assert!((si.t - 8.0).abs() < 1e-5 && (si.ng - Vec3::Z).length() < 1e-5);
    let si = s
        .scene
        .intersect(&ray([0.0, 0.0, -10.0], [0.0, 1.0, 0.0]))
        .unwrap();
    assert!((si.t - 2.0).abs() < 1e-5, "from inside");
    assert!(s
        .scene
        .intersect(&ray([2.001, 0.0, 0.0], [0.0, 0.0, -1.0]))
        .is_none());
    let si = s
        .scene
        .intersect(&ray([1.999, 0.0, 0.0], [0.0, 0.0, -1.0]))
        .unwrap();
    assert!(
        (si.p.x - 1.999).abs() < 1e-5,
        "grazing hit near the silhouette"
    );
}

#[test]
fn nearest_of_overlapping_shapes_wins() {
    let s = scene(
        r#"<shape type="rectangle"><transform name="to_world"><translate z="-5"/></transform></shape>
        <shape type="sphere"><point name="center" x="0" y="0" z="-3"/><float name="radius" value="0.5"/></shape>
        <shape type="disk"><transform name="to_world"><translate z="-4"/></transform></shape>
        <shape type="cube"><transform name="to_world"><scale value="0.25"/><translate z="-1.5"/></transform></shape>"#,
    );
    let order = [(3u32, 1.25f32), (1, 2.5), (2, 4.0), (0, 5.0)];
    let mut o = [0.0f32, 0.0, 0.0];
    for (shape, t) in order {
        let si = s.scene.intersect(&ray(o, [0.0, 0.0, -1.0])).unwrap();
        assert_eq!(si.shape, shape);
        assert!(
            (si.t + (-o[2]) - t).abs() < 1e-5,
            "shape {shape} at {}",
            si.t
        );
        // continue from just past this shape's far side
        o[2] = -(t + if shape == 1 {
            1.01
        } else if shape == 3 {
            0.51
        } else {
            0.01
        });
    }
    assert!(s.scene.intersect(&ray(o, [0.0, 0.0, -1.0])).is_none());
}

/// Rays from random points towards a shape; from each hit, rays leave in random directions
/// on both sides. Flat and convex surfaces must never be hit again by a ray leaving them
/// outward; a ray entering a sphere must reach its far side, not the point it left.
fn reintersection(scale: f64, offset: f64) {
    let shapes = format!(
        r#"<shape type="rectangle"><transform name="to_world"><rotate x="1" y="2" z="0.5" angle="33"/><scale value="{scale}"/><translate x="{offset}" y="{offset}" z="{offset}"/></transform></shape>
        <shape type="cube"><transform name="to_world"><rotate y="1" angle="20"/><scale value="{scale}"/><translate x="{o2}" y="{offset}" z="{offset}"/></transform></shape>
        <shape type="disk"><transform name="to_world"><rotate x="1" angle="70"/><scale value="{scale}"/><translate x="{offset}" y="{o2}" z="{offset}"/></transform></shape>
        <shape type="sphere"><float name="radius" value="{scale}"/><point name="center" x="{offset}" y="{offset}" z="{o2}"/></shape>"#,
        o2 = offset + 3.0 * scale
    );
    let s = scene(&shapes);
    let mut rng = Pcg32::new(0x5eed, 0xda7a);
    let centres = [
        [offset, offset, offset],
        [offset + 3.0 * scale, offset, offset],
        [offset, offset + 3.0 * scale, offset],
        [offset, offset, offset + 3.0 * scale],
    ];
    let mut hits = 0;
    for i in 0..4000 {
        let c = centres[i % 4];
        let dir = Vec3::new(
            rng.random::<f32>() - 0.5,
            rng.random::<f32>() - 0.5,
            rng.random::<f32>() - 0.5,
        )
        .normalize();
        let target = Vec3::new(
            (c[0] + (rng.random::<f64>() - 0.5) * scale) as f32,
            (c[1] + (rng.random::<f64>() - 0.5) * scale) as f32,
            (c[2] + (rng.random::<f64>() - 0.5) * scale) as f32,
        );
        let o = target - dir * (4.0 * scale) as f32;
        let Some(si) = s.scene.intersect(&Ray::new(o, dir, f32::INFINITY)) else {
            continue;
        };
        hits += 1;
        for _ in 0..4 {
            let w = Vec3::new(
                rng.random::<f32>() - 0.5,
                rng.random::<f32>() - 0.5,
                rng.random::<f32>() - 0.5,
            )
            .normalize();
            let outward = w.dot(si.ng) > 0.0;
            let next = s.scene.intersect(&Scene::spawn_ray(&si, w));
            match (si.shape, next) {
                (3, Some(n)) if !outward && n.shape == 3 => {
                    // chord through the sphere: length 2 r |cos θ|, up to the origin's
                    // offset of |p_error| along the normal, which moves the far hit by
                    // about that much / |cos θ|
                    let cos = w.dot(si.ng).abs();
                    let chord = 2.0 * scale as f32 * cos;
                    let d = (n.p - si.p).length();
                    let tol = 1e-4 * chord + 4.0 * si.p_error.length() / cos;
                    assert!((d - chord).abs() <= tol, "sphere chord {d} vs {chord} (tol {tol})");
                }
                (1, Some(n)) if !outward && n.shape == 1 => {
                    // inside the cube: reaches another face, well away from the start
                    assert!((n.p - si.p).length() > 1e-4 * scale as f32 || w.dot(si.ng).abs() < 1e-3);
                }
                (shape, Some(n)) => assert!(
                    n.shape != shape,
                    "scale {scale} offset {offset}: ray leaving shape {shape} ({}) re-hit it at t = {}",
                    if outward { "outward" } else { "inward" },
                    n.t
                ),
                (_, None) => {}
            }
        }
    }
    assert!(hits > 2000, "only {hits} primary hits");
}

#[test]
fn spawned_rays_never_rehit_their_surface_at_unit_scale() {
    reintersection(1.0, 0.0);
}

#[test]
fn spawned_rays_never_rehit_their_surface_at_extreme_scales_and_offsets() {
    for (scale, offset) in [
        (1e-4, 0.0),
        (1e4, 0.0),
        (1e-2, 1e5),
        (1.0, 1e5),
        (1e2, -1e5),
    ] {
        reintersection(scale, offset);
    }
}

#[test]
fn directions_with_negative_zero_components_hit() {
    // obvhs misses everything along a direction with a −0.0 component unless it is
    // normalised to +0.0 (the emitter chi-square tests met (−0, 0, −1) from a quadrature grid).
    let scene = common::scene_from_str(
        r#"<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="45"/></sensor>
    <shape type="rectangle"><transform name="to_world"><translate value="0, 0, -2"/></transform></shape>
</scene>"#,
    );
    for d in [
        glam::Vec3::new(-0.0, 0.0, -1.0),
        glam::Vec3::new(-0.0, -0.0, -1.0),
        glam::Vec3::new(0.0, -0.0, -1.0),
    ] {
        let ray = penumbra::geometry::Ray::new(glam::Vec3::ZERO, d, f32::INFINITY);
        let hit = scene.scene.intersect(&ray).expect("hit");
        assert!((hit.t - 2.0).abs() < 1e-6);
        assert!(scene
            .scene
            .occluded(&penumbra::geometry::Ray::new(glam::Vec3::ZERO, d, 10.0)));
    }
}

/// Instanced analytic shapes (and a mesh) are hit where the same shape placed directly is:
/// distance, normal and point, through a scaled, rotated and translated instance (the mesh
/// case with a non-uniform scale is in tests/mitsuba_files.rs).
#[test]
fn instanced_analytic_shapes_hit_like_placed_ones() {
    let t = r#"<transform name="to_world"><scale value="1.5"/><rotate x="1" angle="30"/><translate x="0.5" y="0.2" z="-4"/></transform>"#;
    for shape in ["sphere", "cylinder", "disk", "rectangle", "cube"] {
        let direct = scene(&format!(r#"<shape type="{shape}">{t}</shape>"#));
        let instanced = scene(&format!(
            r#"<shape type="shapegroup" id="g"><shape type="{shape}"/></shape><shape type="instance"><ref id="g"/>{t}</shape>"#
        ));
        let rays = (0..400).map(|i| {
            let (u, v) = ((i % 20) as f32 / 10.0 - 1.0, (i / 20) as f32 / 10.0 - 1.0);
            ray([0.0, 0.0, 0.0], [u * 2.0 + 0.5, v * 2.0 + 0.2, -4.0])
        });
        let checks = HitChecks {
            ng_tolerance: 1e-4,
            surface_details: false,
        };
        let hits = compare_instanced_hits(&direct.scene, &instanced.scene, rays, &checks, shape);
        assert!(hits > 40, "{shape}: {hits} hits");
    }
}
