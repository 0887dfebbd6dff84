//! The `aov` integrator: a plane seen by an orthographic camera, where every AOV has a
//! closed form (depth, position, normals, uv, albedo; zeros where the rays miss), a nested
//! integrator equal to the same render without `aov`, Mitsuba's channel names in the EXR,
//! and one-line errors.

mod common;
use common::*;
use penumbra::integrator::Integrator;
use penumbra::io::exr;
use penumbra::render::render_channels;
use penumbra::render::Job;
use std::process::Command;

const RES: usize = 32;

/// An orthographic camera at y = 3 looking down on [-2, 2]², a 3 x 3 diffuse rectangle at
/// y = 0.5 (reflectance (0.2, 0.4, 0.6)).
fn scene_xml(integrator: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
            {integrator}
            <sensor type="orthographic">
                <transform name="to_world">
                    <scale x="2" y="2"/>
                    <lookat origin="0, 3, 0" target="0, 0, 0" up="0, 0, -1"/>
                </transform>
                <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
                <film type="hdrfilm"><integer name="width" value="{RES}"/><integer name="height" value="{RES}"/>
                    <rfilter type="box"/></film>
            </sensor>
            <shape type="rectangle">
                <transform name="to_world"><scale value="1.5"/><rotate x="1" angle="-90"/><translate y="0.5"/></transform>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf>
            </shape>
            <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        </scene>"#
    )
}

fn channel<'a>(channels: &'a [(String, Vec<f32>)], name: &str) -> &'a [f32] {
    &channels
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no channel {name}"))
        .1
}

/// The channels of a job whose integrator is `aov`.
fn aov_channels(
    job: &Job,
    spp: u32,
    seed: u64,
) -> (penumbra::render::Channels, penumbra::render::RenderStats) {
    let Integrator::Aov(aov) = &job.integrator else {
        panic!("not an aov scene");
    };
    render_channels(&job.scene, aov, spp, seed, None).expect("renders")
}

#[test]
fn aovs_of_a_plane_have_their_closed_forms() {
    let job = scene_from_str(&scene_xml(
        r#"<integrator type="aov"><string name="aovs" value="dd:depth,pp:position,ng:geo_normal,nn:sh_normal,uv:uv,alb:albedo"/></integrator>"#,
    ));
    let (ch, _) = aov_channels(&job, 16, 3);
    let names: Vec<&str> = ch.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "dd.T", "pp.X", "pp.Y", "pp.Z", "ng.X", "ng.Y", "ng.Z", "nn.X", "nn.Y", "nn.Z", "uv.U",
            "uv.V", "alb.R", "alb.G", "alb.B"
        ]
    );
    let pixel = 4.0 / RES as f32; // the view is 4 wide
    let (mut inside, mut outside) = (0, 0);
    for i in 0..RES * RES {
        let (x, z) = (channel(&ch, "pp.X")[i], channel(&ch, "pp.Z")[i]);
        let get = |n: &str| channel(&ch, n)[i];
        if get("dd.T") == 0.0 {
            // a miss: every AOV is zero
            assert!(ch.iter().all(|(_, v)| v[i] == 0.0), "pixel {i}");
            outside += 1;
            continue;
        }
        if x.abs() > 1.5 - pixel || z.abs() > 1.5 - pixel {
            continue; // the plane's edge crosses the pixel: partial coverage
        }
        inside += 1;
        let close = |a: f32, b: f32| (a - b).abs() < 1e-5;
        // Mitsuba's depth is the hit's distance along the camera ray, which an orthographic
        // camera starts at its near plane (near_clip 0.01 by default): 2.5 − 0.01
        assert!(close(get("dd.T"), 2.49), "depth {}", get("dd.T"));
        assert!(close(get("pp.Y"), 0.5));
        for n in ["ng", "nn"] {
            assert!(close(get(&format!("{n}.X")), 0.0) && close(get(&format!("{n}.Y")), 1.0));
            assert!(close(get(&format!("{n}.Z")), 0.0));
        }
        // the rectangle's uv is ((x_l + 1) / 2, (y_l + 1) / 2) in its local square, whose
        // y axis the rotation turns to −z: linear in the position, so the pixel average is
        // the value at the pixel's mean position
        assert!(
            close(get("uv.U"), (x / 1.5 + 1.0) / 2.0),
            "u {} at x {x}",
            get("uv.U")
        );
        assert!(
            close(get("uv.V"), (-z / 1.5 + 1.0) / 2.0),
            "v {} at z {z}",
            get("uv.V")
        );
        for (c, r) in ["alb.R", "alb.G", "alb.B"].iter().zip([0.2, 0.4, 0.6]) {
            assert!(close(get(c), r), "{c} {}", get(c));
        }
    }
    // the plane covers 3 x 3 of the 4 x 4 view
    assert!(
        inside > 400 && outside > 200,
        "{inside} inside, {outside} outside"
    );
}

#[test]
fn nested_integrator_renders_as_without_aov() {
    let job = scene_from_str(&scene_xml(
        r#"<integrator type="aov"><string name="aovs" value="dd:depth"/>
             <integrator type="path" name="img"><integer name="max_depth" value="3"/></integrator>
           </integrator>"#,
    ));
    let (ch, _) = aov_channels(&job, 16, 5);
    assert_eq!(ch[0].0, "img.R");
    let plain = scene_from_str(&scene_xml(
        r#"<integrator type="path"><integer name="max_depth" value="3"/></integrator>"#,
    ));
    let image = render_scene(&plain, 16, 5, None).film.image();
    for (c, name) in ["img.R", "img.G", "img.B"].iter().enumerate() {
        let ours = channel(&ch, name);
        assert!(ours.iter().zip(&image).all(|(a, p)| *a == p[c]), "{name}");
    }
    assert!(channel(&ch, "img.G").iter().any(|v| *v > 0.1));
}

#[test]
fn cli_writes_the_channels_and_refuses_what_does_not_apply() {
    let dir = std::env::temp_dir().join(format!("penumbra-aov-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let xml = dir.join("aov.xml");
    std::fs::write(
        &xml,
        scene_xml(r#"<integrator type="aov"><string name="aovs" value="dd.y:depth,nn:sh_normal"/></integrator>"#),
    )
    .unwrap();
    let out = dir.join("aov.exr");
    let bin = env!("CARGO_BIN_EXE_penumbra");
    let o = Command::new(bin)
        .args([
            "render".as_ref(),
            xml.as_os_str(),
            "-o".as_ref(),
            out.as_os_str(),
            "-q".as_ref(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ((w, h), channels) = exr::read_channels(&out).unwrap();
    assert_eq!((w, h), (RES, RES));
    let mut names: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
    names.sort();
    assert_eq!(names, ["dd.y.T", "nn.X", "nn.Y", "nn.Z"]);
    let o = Command::new(bin)
        .args([
            "render".as_ref(),
            xml.as_os_str(),
            "--variance".as_ref(),
            "-o".as_ref(),
            out.as_os_str(),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.lines().count() == 1 && err.contains("--variance"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_aov_lists_are_one_line_errors() {
    for (body, expect) in [
        (
            r#"<string name="aovs" value="dd:velocity"/>"#,
            "unsupported type",
        ),
        (r#"<string name="aovs" value="depth"/>"#, "name:type"),
        (r#"<string name="aovs" value=""/>"#, "no AOVs"),
        (
            r#"<string name="aovs" value="dd:depth"/><integrator type="path"/>"#,
            "needs a name",
        ),
    ] {
        let xml = scene_xml(&format!(r#"<integrator type="aov">{body}</integrator>"#));
        let err = Job::from_xml_str(&xml, &repo_path("tests/inline.xml"), &[])
            .err()
            .unwrap_or_else(|| panic!("{body} was accepted"))
            .to_string();
        assert!(err.contains(expect) && !err.contains('\n'), "{err}");
    }
}
