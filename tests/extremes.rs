//! Issue 40's extremes through the command line: the Cornell box lit at 2^-66 and 2^53 (and
//! at the literal 1e-20 and 1e16) renders the unit image times the factor; a tiny emitter of
//! radiance 2^100 renders its unit image times 2^100 without a refusal; numbers beyond the
//! single-precision range penumbra renders in are refused at load with one line.

mod common;
use common::repo_path;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("penumbra-extremes-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
    fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn penumbra(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .output()
        .expect("cannot run penumbra")
}

/// Renders `scene` with the CLI (16x16, 32 spp, seed 3) and reads the EXR's pixels.
fn render(dir: &TempDir, scene: &Path, name: &str) -> Vec<[f32; 3]> {
    let out = dir.0.join(format!("{name}.exr"));
    let o = penumbra(&[
        "render".as_ref(),
        scene.as_os_str(),
        "-D".as_ref(),
        "res=16".as_ref(),
        "--spp".as_ref(),
        "32".as_ref(),
        "--seed".as_ref(),
        "3".as_ref(),
        "-q".as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    penumbra::io::exr::read(&out).unwrap().rgb
}

/// The Cornell box with its light's radiance times `factor` (each component printed in the
/// shortest decimal that reads back to the f64 product).
fn cornell(factor: f64) -> String {
    let xml = std::fs::read_to_string(repo_path("scenes/cornell-box.xml")).unwrap();
    let unit = r#"<rgb name="radiance" value="18.387, 13.9873, 6.75357"/>"#;
    assert!(xml.contains(unit));
    let v: Vec<String> = [18.387f64, 13.9873, 6.75357]
        .iter()
        .map(|x| format!("{:e}", x * factor))
        .collect();
    xml.replace(
        unit,
        &format!(r#"<rgb name="radiance" value="{}"/>"#, v.join(", ")),
    )
    .replace(
        "meshes/",
        &format!("{}/", repo_path("scenes/meshes").display()),
    )
}

#[test]
fn the_cornell_box_renders_at_any_scale_through_the_cli() {
    let dir = TempDir::new("scale");
    let unit = render(&dir, &dir.write("unit.xml", &cornell(1.0)), "unit");
    assert!(unit.iter().flatten().any(|v| *v > 0.1), "a lit image");
    // Powers of two: every f32 product scales exactly (nothing underflows), so the image is
    // the unit one times the factor, bit for bit.
    for e in [-66, 53] {
        let s = 2f64.powi(e);
        let img = render(&dir, &dir.write("pow2.xml", &cornell(s)), "pow2");
        for (p, (a, b)) in unit.iter().zip(&img).enumerate() {
            for c in 0..3 {
                assert_eq!(
                    (a[c] as f64 * s) as f32,
                    b[c],
                    "2^{e}: pixel {p} channel {c}: {} vs {}",
                    a[c],
                    b[c]
                );
            }
        }
    }
    // Literal factors: L · s rounds once in f32, so a few ulps per pixel.
    for s in [1e-20, 1e16] {
        let img = render(&dir, &dir.write("lit.xml", &cornell(s)), "lit");
        for (p, (a, b)) in unit.iter().zip(&img).enumerate() {
            for c in 0..3 {
                let want = a[c] as f64 * s;
                let rel = (b[c] as f64 - want).abs() / want.abs().max(1e-300);
                assert!(
                    rel < 8.0 * f32::EPSILON as f64 || (want == 0.0 && b[c] == 0.0),
                    "{s:e}: pixel {p} channel {c}: {} vs {want:e}",
                    b[c]
                );
            }
        }
    }
}

/// A tiny sphere light of radiance 2^100 (a firefly wherever a path finds it) renders; its
/// image is the unit light's times 2^100, bit for bit.
#[test]
fn a_firefly_of_1e30_is_rendered_exactly() {
    let dir = TempDir::new("firefly");
    let scene = |radiance: &str| {
        format!(
            r#"<scene version="3.0.0"><default name="res" value="16"/>
<integrator type="path"><integer name="max_depth" value="4"/></integrator>
<sensor type="perspective"><float name="fov" value="40"/>
<transform name="to_world"><lookat origin="0, 1, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
<film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="$res"/><rfilter type="gaussian"/></film></sensor>
<shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform></shape>
<shape type="sphere"><point name="center" x="0.3" y="0.4" z="0"/><float name="radius" value="0.01"/>
<emitter type="area"><float name="radiance" value="{radiance}"/></emitter></shape>
</scene>"#
        )
    };
    let unit = render(&dir, &dir.write("unit.xml", &scene("1")), "unit");
    // 2^100 = 1267650600228229401496703205376 exactly.
    let big = render(
        &dir,
        &dir.write("big.xml", &scene("1267650600228229401496703205376")),
        "big",
    );
    let s = 2f64.powi(100);
    // (the floor under the light: 2^100 times its unit irradiance)
    assert!(unit.iter().flatten().any(|v| *v > 1e-4), "the light lands");
    assert!(big.iter().flatten().any(|v| *v > 1e26), "the firefly lands");
    for (a, b) in unit.iter().zip(&big) {
        for c in 0..3 {
            assert_eq!((a[c] as f64 * s) as f32, b[c]);
        }
    }
}

/// Numbers beyond f32's range (where penumbra computes in f32) are refused at load, with the
/// element's line: they used to render black (every sample dropped as non-finite), exit 0.
#[test]
fn numbers_beyond_single_precision_are_refused() {
    let dir = TempDir::new("range");
    let base = |body: &str| {
        format!(
            r#"<scene version="3.0.0"><integrator type="path"/>
<sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
{body}
</scene>"#
        )
    };
    let sky = repo_path("scenes/textures/sky-64x32.exr");
    for (name, body, expect) in [
        (
            "radiance",
            r#"<shape type="sphere"><emitter type="area"><rgb name="radiance" value="1e39, 1, 1"/></emitter></shape>"#.to_string(),
            "exceeds the single-precision range",
        ),
        (
            "transform",
            r#"<shape type="sphere"><transform name="to_world"><translate x="1e39"/></transform></shape><emitter type="constant"/>"#.to_string(),
            "exceeds the single-precision range",
        ),
        (
            "spectrum",
            r#"<shape type="sphere"><emitter type="area"><spectrum name="radiance" value="400:1e39, 700:1e39"/></emitter></shape>"#.to_string(),
            "beyond the single-precision range",
        ),
        (
            "envmap-scale",
            format!(r#"<emitter type="envmap"><string name="filename" value="{}"/><float name="scale" value="3e38"/></emitter>"#, sky.display()),
            "emission overflows the single-precision range",
        ),
    ] {
        let scene = dir.write(&format!("{name}.xml"), &base(&body));
        let o = penumbra(&[
            "render".as_ref(),
            scene.as_os_str(),
            "-o".as_ref(),
            dir.0.join("x.exr").as_os_str(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert_eq!(err.lines().count(), 1, "{name}: {err}");
        assert!(err.starts_with("error: ") && err.contains(expect), "{name}: {err}");
    }
}
