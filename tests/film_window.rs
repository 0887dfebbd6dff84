//! The film's crop window and the perspective sensor's principal point shift: camera rays and
//! camera connections against Mitsuba 3.9.1's (tests/data/mitsuba_window_rays.txt, from
//! validation/mitsuba/window_rays.py), and a crop that renders the same pixels as the whole
//! film, bit for bit.

mod common;
use common::{render_scene, scene_from_str};
use glam::{DVec2, DVec3, Vec2};

const MITSUBA: &str = include_str!("data/mitsuba_window_rays.txt");

struct Case {
    name: String,
    plugin: String,
    size: (u32, u32),
    crop: [u32; 4],
    ppo: (f64, f64),
    fov: f64,
    ops: String,
    origin: DVec3,
    rays: Vec<Vec<f64>>,
    connections: Vec<Vec<f64>>,
}

fn cases() -> Vec<Case> {
    let mut cases: Vec<Case> = Vec::new();
    for line in MITSUBA.lines().filter(|l| !l.starts_with('#')) {
        let (tag, rest) = line.split_once(' ').unwrap();
        let nums = || -> Vec<f64> { rest.split(' ').map(|x| x.parse().unwrap()).collect() };
        match tag {
            "case" => {
                let f: Vec<&str> = rest.split(' ').collect();
                let u = |i: usize| f[i].parse::<u32>().unwrap();
                cases.push(Case {
                    name: f[0].into(),
                    plugin: f[1].into(),
                    size: (u(2), u(3)),
                    crop: [u(4), u(5), u(6), u(7)],
                    ppo: (f[8].parse().unwrap(), f[9].parse().unwrap()),
                    fov: f[10].parse().unwrap(),
                    ops: String::new(),
                    origin: DVec3::ZERO,
                    rays: vec![],
                    connections: vec![],
                })
            }
            "xml" => cases.last_mut().unwrap().ops = rest.into(),
            "origin" => {
                let v = nums();
                cases.last_mut().unwrap().origin = DVec3::new(v[0], v[1], v[2]);
            }
            "r" => cases.last_mut().unwrap().rays.push(nums()),
            "c" => cases.last_mut().unwrap().connections.push(nums()),
            _ => panic!("unknown record {tag}"),
        }
    }
    assert_eq!(cases.len(), 5, "the data file has five cases");
    cases
}

fn scene_xml(c: &Case) -> String {
    let mut props = String::new();
    if c.plugin == "perspective" {
        props = format!(
            r#"<float name="fov" value="{}"/><float name="principal_point_offset_x" value="{}"/><float name="principal_point_offset_y" value="{}"/>"#,
            c.fov, c.ppo.0, c.ppo.1
        );
    }
    let [x, y, w, h] = c.crop;
    format!(
        r#"<scene version="3.0.0"><integrator type="path"/>
<sensor type="{}">{props}<transform name="to_world">{}</transform>
<film type="hdrfilm"><integer name="width" value="{}"/><integer name="height" value="{}"/>
<integer name="crop_offset_x" value="{x}"/><integer name="crop_offset_y" value="{y}"/>
<integer name="crop_width" value="{w}"/><integer name="crop_height" value="{h}"/>
<rfilter type="box"/></film></sensor>
<shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
</scene>"#,
        c.plugin, c.ops, c.size.0, c.size.1
    )
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).abs().max_element() <= tol
}

/// Rays through positions of the crop window (Mitsuba's position samples are relative to
/// it) and connections of world points to the pinhole, with a crop window, a principal
/// point shift, both, and an orthographic crop.
#[test]
fn rays_and_connections_match_mitsuba() {
    let (mut compared, mut mitsuba_zero) = (0, 0);
    for c in cases() {
        let scene = scene_from_str(&scene_xml(&c));
        assert_eq!(
            (scene.scene.width, scene.scene.height),
            (c.crop[2] as usize, c.crop[3] as usize)
        );
        // penumbra builds the scene around the camera: world = camera-relative + origin.
        for r in &c.rays {
            let ray = scene
                .scene
                .camera
                .generate_ray(Vec2::new(r[0] as f32, r[1] as f32));
            let o = ray.o.as_dvec3() + c.origin;
            let d = ray.d.as_dvec3();
            let (mo, md) = (DVec3::new(r[2], r[3], r[4]), DVec3::new(r[5], r[6], r[7]));
            assert!(close(d, md, 2e-6), "{}: d {d} vs {md} at {r:?}", c.name);
            assert!(close(o, mo, 2e-5), "{}: o {o} vs {mo}", c.name);
            let rel = (ray.tmax as f64 - r[8]).abs() / r[8];
            assert!(rel < 1e-5, "{}: maxt {} vs {}", c.name, ray.tmax, r[8]);
        }
        let crop = DVec2::new(c.crop[2] as f64, c.crop[3] as f64);
        for k in &c.connections {
            let p = DVec3::new(k[0], k[1], k[2]) - c.origin;
            let ours = scene.scene.camera.sample_direction(p.as_vec3());
            assert_eq!(ours.is_some(), k[3] == 1.0, "{}: valid at {p}", c.name);
            if let Some(s) = ours {
                let uv = s.film.as_dvec2() * crop;
                let muv = DVec2::new(k[4], k[5]);
                assert!(
                    (uv - muv).abs().max_element() < 1e-3,
                    "{}: pixel {uv} vs {muv}",
                    c.name
                );
                // Mitsuba 3.9.1's `importance` tests the direction against the image
                // rectangle *without* the principal point shift, so it returns 0 for points
                // that its own `sample_direction` places inside the shifted window (its
                // ptracer then drops them). penumbra's W_e covers the window it renders;
                // where Mitsuba's is not 0 the two agree.
                if k[6] == 0.0 {
                    assert!(
                        c.ppo != (0.0, 0.0),
                        "{}: zero importance without a shift",
                        c.name
                    );
                    mitsuba_zero += 1;
                    continue;
                }
                let rel = (s.weight as f64 - k[6]).abs() / k[6];
                assert!(rel < 1e-4, "{}: W_e/d² {} vs {}", c.name, s.weight, k[6]);
                compared += 1;
            }
        }
        assert_eq!(
            c.connections.is_empty(),
            c.plugin != "perspective",
            "{}: connections for perspective cases",
            c.name
        );
    }
    assert_eq!((compared, mitsuba_zero), (12, 4));
}

/// With the box filter a crop of the film renders the pixels of the whole film it covers
/// with the same random numbers (samples are keyed by film pixels): equal to the last bits
/// of the film position (crop position · crop scale + offset rounds differently from the
/// whole film's position).
#[test]
fn a_crop_renders_the_same_pixels_as_the_whole_film() {
    let xml = |crop: &str| {
        format!(
            r#"<scene version="3.0.0"><integrator type="path"><integer name="max_depth" value="3"/></integrator>
<sensor type="perspective"><float name="fov" value="40"/>
<transform name="to_world"><lookat origin="0, 0.3, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
<sampler type="stratified"><integer name="sample_count" value="4"/></sampler>
<film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="30"/>{crop}
<rfilter type="box"/></film></sensor>
<shape type="sphere"/>
<shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/><translate y="-1"/></transform></shape>
<emitter type="constant"><rgb name="radiance" value="0.7, 0.8, 1"/></emitter>
</scene>"#
        )
    };
    let full = scene_from_str(&xml(""));
    let crop = scene_from_str(&xml(
        r#"<integer name="crop_offset_x" value="7"/><integer name="crop_offset_y" value="11"/><integer name="crop_width" value="17"/><integer name="crop_height" value="13"/>"#,
    ));
    let a = render_scene(&full, 4, 3, Some(2)).film.image();
    let b = render_scene(&crop, 4, 3, Some(1)).film.image();
    assert_eq!(b.len(), 17 * 13);
    let mut distinct = 0;
    for y in 0..13 {
        for x in 0..17 {
            let (p, q) = (a[(y + 11) * 40 + x + 7], b[y * 17 + x]);
            for c in 0..3 {
                assert!(
                    (p[c] - q[c]).abs() <= 1e-5 * p[c].abs().max(1e-3),
                    "pixel ({x}, {y}) of the crop: {p:?} vs {q:?}"
                );
            }
            distinct += (p != a[(y + 11) * 40 + x + 8]) as usize;
        }
    }
    // (the pixels differ from each other: the comparison is not of a constant image)
    assert!(distinct > 100, "{distinct}");
}
