//! Numerical robustness at the extremes: the same scene at any scale or distance from the
//! origin renders the same image; exact accumulation at 2^20 samples; no non-finite sample in
//! any shipped scene; closed meshes let no ray through, even at edges and vertices.

mod common;
use common::*;
use glam::Vec3;
use penumbra::geometry::Ray;
use penumbra::io::exr::RgbImage;
use penumbra::render::Job;
use penumbra::render::RenderOutput;
use penumbra::scene::Scene;
use penumbra::study::metrics::{channel_means, z_test};
use std::collections::BTreeMap;

/// The Cornell box with every shape and the camera scaled by `s` about the origin, then
/// translated by (o, o, o); clipping planes scaled with it.
fn transformed_cornell(s: f64, o: f64) -> String {
    let xml = std::fs::read_to_string(repo_path("scenes/cornell-box.xml")).unwrap();
    let xml = xml.replace(
        "</transform>",
        &format!(r#"<scale value="{s}"/><translate value="{o}, {o}, {o}"/></transform>"#),
    );
    let near = format!(r#"name="near_clip" value="{}""#, 0.001 * s);
    let far = format!(r#"name="far_clip" value="{}""#, 100.0 * s);
    let xml = xml
        .replace(r#"name="near_clip" value="0.001""#, &near)
        .replace(r#"name="far_clip" value="100""#, &far);
    assert!(xml.contains(&near) && xml.contains(&far));
    xml
}

fn render_image(xml: &str, spp: u32, seed: u64) -> (RgbImage, RenderOutput) {
    let scene = Job::from_xml_str(
        xml,
        &repo_path("scenes/inline.xml"),
        &[("res".into(), "96".into())],
    )
    .expect("scene builds");
    let out = render_scene(&scene, spp, seed, None);
    assert_eq!(out.stats.nonfinite, 0);
    let img = RgbImage {
        width: scene.scene.width,
        height: scene.scene.height,
        rgb: out.film.image(),
        variance: Some(out.film.sample_variance()),
        attributes: BTreeMap::new(),
    };
    (img, out)
}

#[test]
fn cornell_box_is_invariant_under_scale_and_translation() {
    let spp = 64;
    let (unit, _) = render_image(&transformed_cornell(1.0, 0.0), spp, 1);
    let (unit_same_seed, _) = render_image(&transformed_cornell(1.0, 0.0), spp, 2);
    let m_unit = channel_means(&unit.rgb);
    for (s, o) in [
        (1e-4, 0.0),
        (1e-2, 0.0),
        (1e2, 0.0),
        (1e4, 0.0),
        (1.0, 1e3),
        (1.0, 1e5),
        (1e-2, 1e5),
        (1e4, -1e5),
    ] {
        let (img, _) = render_image(&transformed_cornell(s, o), spp, 2);
        let m = channel_means(&img.rgb);
        // Same seed as `unit_same_seed`: how far from identical the transformed render is.
        let same = penumbra::study::metrics::error_metrics(&img.rgb, &unit_same_seed.rgb);
        eprintln!(
            "scale {s:e} offset {o:e}: same-seed max abs pixel difference {:.3e}, RMSE {:.3e}",
            same.max_abs, same.rmse
        );
        for c in 0..3 {
            let rel = (m[c] - m_unit[c]).abs() / m_unit[c];
            assert!(
                rel < 0.005,
                "scale {s} offset {o}: channel {c} mean {} vs {} ({rel:.4})",
                m[c],
                m_unit[c]
            );
        }
        let t = z_test(&img, spp as f64, &unit, spp as f64, 0.01).unwrap();
        eprintln!(
            "scale {s:e} offset {o:e}: mean rel. diff R {:+.4}% G {:+.4}% B {:+.4}%, z-test pass {:.4}%, max |z| {:.2}",
            100.0 * (m[0] / m_unit[0] - 1.0),
            100.0 * (m[1] / m_unit[1] - 1.0),
            100.0 * (m[2] / m_unit[2] - 1.0),
            100.0 * t.pass_rate(),
            t.z_max
        );
        assert!(
            t.passed(),
            "scale {s} offset {o}: z-test {} of {} fail, max |z| {:.2}",
            t.failures,
            t.tests,
            t.z_max
        );
    }
}

#[test]
fn a_pixel_seeing_only_an_emitter_is_exact_at_2_pow_20_samples() {
    // A 1x1 film looking at a large emitting rectangle; max_depth 1 (emission only).
    let xml = r#"<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="1"/></integrator>
        <sensor type="perspective"><float name="fov" value="10"/>
            <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/><rfilter type="box"/></film></sensor>
        <shape type="rectangle"><transform name="to_world"><scale value="10"/><translate z="5"/></transform>
            <boolean name="flip_normals" value="true"/>
            <emitter type="area"><rgb name="radiance" value="0.1, 3.7, 12345.678"/></emitter></shape>
    </scene>"#;
    let scene = scene_from_str(xml);
    let out = render_scene(&scene, 1 << 20, 3, None);
    let expected = [0.1f32, 3.7, 12345.678];
    assert_eq!(out.film.image()[0], expected);
    assert_eq!(out.film.weight[0], (1u64 << 20) as f64);
    // E[x²] − E[x]² from f64 sums of 2^20 squares: each addition rounds at 2^-53, so the
    // variance of a constant is zero up to 2^20 · 2^-53 = 2^-33 relative to x².
    for (v, l) in out.film.sample_variance()[0].iter().zip(expected) {
        assert!(*v as f64 <= (l as f64).powi(2) * 2f64.powi(-33), "{v}");
    }
}

#[test]
fn no_shipped_scene_produces_non_finite_samples() {
    let mut checked = 0;
    let entries = ["scenes", "scenes/ladder"]
        .iter()
        .flat_map(|dir| std::fs::read_dir(repo_path(dir)).unwrap());
    for entry in entries {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("xml") {
            continue;
        }
        let scene = Job::load(&path, &[("res".into(), "32".into())]).expect("shipped scene loads");
        let out = render_scene(&scene, 16, 5, None);
        assert_eq!(out.stats.nonfinite, 0, "{}", path.display());
        checked += 1;
    }
    assert!(checked >= 20, "{checked} scenes");
}

/// An icosphere-like closed mesh: a subdivided octahedron projected to the unit sphere.
fn closed_sphere_mesh(subdiv: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut verts = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    for _ in 0..subdiv {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        let mut midpoint = |a: u32, b: u32, verts: &mut Vec<Vec3>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                (verts.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut verts);
            let bc = midpoint(b, c, &mut verts);
            let ca = midpoint(c, a, &mut verts);
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        tris = next;
    }
    (verts, tris)
}

#[test]
fn no_ray_slips_through_a_closed_mesh_at_its_edges_and_vertices() {
    let (verts, tris) = closed_sphere_mesh(3);
    let dir = std::env::temp_dir().join(format!("penumbra-closed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut obj = String::new();
    for v in &verts {
        obj += &format!("v {} {} {}\n", v.x, v.y, v.z);
    }
    for t in &tris {
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(dir.join("closed.obj"), obj).unwrap();
    for (scale, offset) in [(1.0f32, 0.0f32), (1e-3, 0.0), (1e3, 0.0), (1.0, 1e4)] {
        let xml = format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="30"/>
            <transform name="to_world"><lookat origin="{offset},{offset},{o2}" target="{offset},{offset},{offset}" up="0,1,0"/></transform>
            <film type="hdrfilm"><integer name="width" value="2"/><integer name="height" value="2"/><rfilter type="box"/></film></sensor>
            <shape type="obj"><string name="filename" value="closed.obj"/><boolean name="face_normals" value="true"/>
            <transform name="to_world"><scale value="{scale}"/><translate value="{offset},{offset},{offset}"/></transform></shape></scene>"#,
            o2 = offset + 10.0 * scale
        );
        let scene = Job::from_xml_str(&xml, &dir.join("s.xml"), &[]).unwrap();
        // The build is camera-relative: the sphere's centre sits at (0, 0, -10 scale).
        let centre = Vec3::new(0.0, 0.0, -10.0 * scale);
        let mut targets: Vec<Vec3> = verts.clone();
        for t in &tris {
            let [a, b, c] = t.map(|i| verts[i as usize]);
            targets.push((a + b) * 0.5);
            targets.push(a * 0.3 + b * 0.7);
            targets.push((a + b + c) / 3.0);
        }
        let mut hits = 0;
        for (i, t) in targets.iter().enumerate() {
            let target = centre + *t * scale;
            // from the centre outwards, and from outside inwards, aimed at the vertex/edge
            let from_inside = Ray::new(centre, (target - centre).normalize(), f32::INFINITY);
            assert!(
                scene.scene.intersect(&from_inside).is_some(),
                "scale {scale} offset {offset}: inside ray {i} escaped"
            );
            // Within ~6° of the radial direction, so the ray enters the (convex) mesh at the
            // target rather than touching it at a silhouette vertex.
            let skew = Vec3::new(0.3, -0.2, 0.1) * ((i as f32 % 7.0 - 3.0) * 0.03);
            let o = target + (*t + skew).normalize() * (3.0 * scale);
            let d = (target - o).normalize();
            let si = scene.scene.intersect(&Ray::new(o, d, f32::INFINITY));
            let si = si
                .unwrap_or_else(|| panic!("scale {scale} offset {offset}: outside ray {i} missed"));
            // ...and a ray continuing from that hit into the sphere must hit it again.
            let next = scene.scene.intersect(&Scene::spawn_ray(&si, d));
            assert!(
                next.is_some(),
                "scale {scale} offset {offset}: ray {i} passed through the mesh"
            );
            hits += 1;
        }
        assert_eq!(hits, targets.len());
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A mesh with duplicated vertices (the same position under several indices) and a huge range
/// of coordinates within one mesh (a 1e-3 triangle fan next to 1e6-sized triangles): rays aimed
/// at the small fan's vertices and edges hit it, and a ray spawned from every hit never hits
/// the triangle it leaves (the huge triangles' coordinates do not degrade the small ones).
#[test]
fn duplicate_vertices_and_huge_coordinate_ranges_in_one_mesh() {
    let dir = std::env::temp_dir().join(format!("penumbra-ranges-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let s = 1e-3f32;
    let mut obj = String::new();
    // small fan around the origin in z = 0, every triangle with its own copies of the
    // centre and rim vertices (duplicates)
    for k in 0..8 {
        let a0 = k as f32 * std::f32::consts::FRAC_PI_4;
        let a1 = a0 + std::f32::consts::FRAC_PI_4;
        obj += "v 0 0 0\n";
        obj += &format!("v {} {} 0\n", s * a0.cos(), s * a0.sin());
        obj += &format!("v {} {} 0\n", s * a1.cos(), s * a1.sin());
    }
    // huge triangles far away in the same mesh
    obj += "v 1e6 1e6 -5\nv -1e6 1e6 -5\nv 0 -1e6 -5\nv 1e6 -1e6 50000\nv 1e6 1e6 50000\nv 2e6 0 -50000\n";
    for k in 0..8 {
        obj += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
    }
    obj += "f 25 26 27\nf 28 29 30\n";
    std::fs::write(dir.join("ranges.obj"), obj).unwrap();
    let xml = r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="30"/>
        <transform name="to_world"><lookat origin="0,0,1" target="0,0,0" up="0,1,0"/></transform>
        <film type="hdrfilm"><integer name="width" value="2"/><integer name="height" value="2"/><rfilter type="box"/></film></sensor>
        <shape type="obj"><string name="filename" value="ranges.obj"/><boolean name="face_normals" value="true"/></shape></scene>"#;
    let scene = Job::from_xml_str(xml, &dir.join("s.xml"), &[]).unwrap();
    // camera-relative: the fan sits at z = -1
    let centre = Vec3::new(0.0, 0.0, -1.0);
    let mut targets = vec![centre];
    for k in 0..8 {
        let a = k as f32 * std::f32::consts::FRAC_PI_4;
        let rim = centre + Vec3::new(s * a.cos(), s * a.sin(), 0.0);
        targets.push(rim * 0.999 + centre * 0.001); // just inside the rim vertex
        targets.push((centre + rim) * 0.5); // on a shared interior edge
    }
    for (i, t) in targets.iter().enumerate() {
        for d in [
            Vec3::new(0.1, 0.2, -1.0),
            Vec3::new(-0.3, 0.05, -1.0),
            Vec3::new(0.0, 0.0, -1.0),
        ] {
            let d = d.normalize();
            let o = *t - d * 0.5;
            let si = scene
                .scene
                .intersect(&Ray::new(o, d, f32::INFINITY))
                .unwrap_or_else(|| panic!("target {i}: the ray slipped through the fan"));
            assert!(
                (si.p - *t).length() < 1e-6,
                "target {i}: hit {} instead of {}",
                si.p,
                t
            );
            for w in [
                si.ng,
                -si.ng,
                (si.ng + Vec3::X).normalize(),
                (Vec3::Y - si.ng).normalize(),
            ] {
                if let Some(next) = scene.scene.intersect(&Scene::spawn_ray(&si, w)) {
                    assert!(
                        (next.p - si.p).length() > 1.0,
                        "target {i}: a ray leaving the fan re-hit it at {}",
                        next.p
                    );
                }
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Materials at the extremes of issue 6 (alpha 1e-4 and 1, IOR 1.0001 and 4, k 10, radiance
/// 1e-6 and 1e6 lighting them): eval, pdf and sample give finite, non-negative values for
/// directions down to cos θ = ±1e-7, and rendering them drops no sample as non-finite.
#[test]
fn extreme_materials_give_no_nan_or_inf() {
    let bsdfs = [
        r#"<bsdf type="roughconductor"><float name="alpha" value="0.0001"/></bsdf>"#,
        r#"<bsdf type="roughconductor"><string name="distribution" value="beckmann"/><float name="alpha" value="1"/></bsdf>"#,
        r#"<bsdf type="roughconductor"><float name="alpha_u" value="0.0001"/><float name="alpha_v" value="1"/></bsdf>"#,
        r#"<bsdf type="conductor"><rgb name="eta" value="0.1, 4, 1"/><rgb name="k" value="10, 10, 0"/></bsdf>"#,
        r#"<bsdf type="roughdielectric"><float name="alpha" value="0.0001"/><float name="int_ior" value="1.0001"/></bsdf>"#,
        r#"<bsdf type="roughdielectric"><float name="alpha" value="1"/><float name="int_ior" value="4"/></bsdf>"#,
        r#"<bsdf type="dielectric"><float name="int_ior" value="1.0001"/></bsdf>"#,
        r#"<bsdf type="thindielectric"><float name="int_ior" value="4"/></bsdf>"#,
        r#"<bsdf type="roughplastic"><float name="alpha" value="0.0001"/><float name="int_ior" value="4"/></bsdf>"#,
        r#"<bsdf type="plastic"><float name="int_ior" value="1.0001"/></bsdf>"#,
    ];
    let mut dirs = Vec::new();
    for z in [1e-7f32, -1e-7, 1e-4, -1e-4, 0.5, -0.5, 1.0, -1.0] {
        let r = (1.0 - z * z).max(0.0).sqrt();
        for phi in [0.0f32, 1.0, 2.5, 4.0] {
            dirs.push(Vec3::new(r * phi.cos(), r * phi.sin(), z));
        }
    }
    for (i, b) in bsdfs.iter().enumerate() {
        for radiance in ["0.000001", "1000000"] {
            let xml = format!(
                r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="60"/>
                <transform name="to_world"><lookat origin="0,0,3" target="0,0,0" up="0,1,0"/></transform>
                <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/><rfilter type="box"/></film></sensor>
                <shape type="sphere">{b}</shape>
                <shape type="rectangle"><transform name="to_world"><scale value="5"/><translate z="-2"/></transform></shape>
                <shape type="disk"><transform name="to_world"><rotate x="1" angle="180"/><translate y="0.5" z="4"/></transform>
                    <emitter type="area"><rgb name="radiance" value="{radiance}"/></emitter></shape></scene>"#
            );
            let scene = scene_from_str(&xml);
            let out = render_scene(&scene, 32, 9, None);
            assert_eq!(out.stats.nonfinite, 0, "bsdf {i} radiance {radiance}");
            let ctx = penumbra::material::ShadingContext {
                tex: penumbra::texture::TextureContext::at_uv(glam::Vec2::splat(0.5)),
                frame: penumbra::geometry::Frame::from_normal(Vec3::Z),
                dp_du: Vec3::X,
                dp_dv: Vec3::Y,
                ng: Vec3::Z,
            };
            let bsdf = penumbra::material::Material::shading_bsdf(
                &scene.scene.materials,
                scene.scene.shapes[0].material,
                &ctx,
            );
            let mut s = penumbra::sampler::SampleStream::new(5, i as u64, 0);
            for &wi in &dirs {
                for &wo in &dirs {
                    let f = bsdf.eval(wi, wo);
                    let p = bsdf.pdf(wi, wo);
                    assert!(
                        f.is_finite() && f.min_element() >= 0.0 && p.is_finite() && p >= 0.0,
                        "bsdf {i}: {wi} {wo}"
                    );
                }
                for _ in 0..64 {
                    if let Some(bs) = bsdf.sample(wi, s.next_1d(), s.next_2d()) {
                        assert!(
                            bs.wo.is_finite() && bs.weight.is_finite() && bs.pdf.is_finite(),
                            "bsdf {i}: sample at {wi}"
                        );
                        assert!(bs.weight.min_element() >= 0.0 && bs.pdf >= 0.0);
                    }
                }
            }
        }
    }
}
