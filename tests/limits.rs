//! Issue 40: the limits a real scene could exceed are set at run time by `PENUMBRA_LIMITS`
//! (src/limits.rs). The parser through the library's API, then the variable end to end
//! through the `penumbra` binary: the variable is read once per process, so every test that
//! sets it runs a subprocess (never sets it in this one).

use penumbra::limits::{Limit, Limits};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A temporary directory unique to this process and test, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("penumbra-limits-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.path(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `penumbra render scene -o dir/out.exr --spp 1` with `PENUMBRA_LIMITS` set to `limits`,
/// or removed (the defaults) for `None`.
fn render(dir: &TempDir, scene: &Path, limits: Option<&str>) -> Output {
    let exr = dir.path("out.exr");
    let _ = std::fs::remove_file(&exr);
    let mut command = Command::new(env!("CARGO_BIN_EXE_penumbra"));
    command
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(&exr)
        .args(["--spp", "1", "--quiet"])
        .env("RUST_BACKTRACE", "1");
    match limits {
        Some(value) => command.env("PENUMBRA_LIMITS", value),
        None => command.env_remove("PENUMBRA_LIMITS"),
    };
    let out = command.output().expect("cannot run penumbra");
    assert_eq!(
        exr.exists(),
        out.status.success(),
        "an image must be written exactly when the render succeeds: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn assert_renders(out: &Output) {
    assert_eq!(
        out.status.code(),
        Some(0),
        "penumbra failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Asserts a clean failure: status 1, exactly one stderr line `error: ...`, nothing on
/// stdout. Returns the line.
fn error_line(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "expected one line on stderr, got: {err}");
    assert!(lines[0].starts_with("error: "), "{err}");
    assert!(out.stdout.is_empty(), "{:?}", out.stdout);
    lines[0].to_string()
}

/// A `size`×`size` film looking down -z at `shapes`, under a constant environment.
fn scene(size: u32, shapes: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"/>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world">
            <lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="{size}"/>
            <integer name="height" value="{size}"/>
        </film>
    </sensor>
    <emitter type="constant"/>
{shapes}
</scene>
"#
    )
}

/// An ASCII PLY of an `n`×`n` grid of quads (two triangles each) in the z = 0 plane.
fn grid_ply(n: usize) -> String {
    let mut vertices = String::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f64 / n as f64 - 0.5, j as f64 / n as f64 - 0.5);
            vertices += &format!("{x} {y} 0\n");
        }
    }
    let mut faces = String::new();
    let at = |i: usize, j: usize| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            faces += &format!("3 {} {} {}\n", at(i, j), at(i + 1, j), at(i + 1, j + 1));
            faces += &format!("3 {} {} {}\n", at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\n\
         end_header\n{vertices}{faces}",
        (n + 1) * (n + 1),
        2 * n * n
    )
}

// ---------------------------------------------------------------------------------------
// The parser (src/limits.rs has the full table of forms)
// ---------------------------------------------------------------------------------------

#[test]
fn the_variable_sets_exactly_the_limits_it_names() {
    let l = Limits::parse("render_pixels=2^28, mesh_bytes=32G,radiosity_rays=1000").unwrap();
    assert_eq!(
        l,
        Limits {
            render_pixels: 268_435_456,
            mesh_bytes: 34_359_738_368,
            radiosity_rays: 1000,
            ..Limits::DEFAULT
        }
    );
    assert_eq!(Limits::parse("").unwrap(), Limits::DEFAULT);
    for (value, expected) in [
        ("1", 1u64),
        ("1K", 1024),
        ("1m", 1 << 20),
        ("3G", 3 << 30),
        ("1T", 1 << 40),
        ("2^40", 1 << 40),
        ("2^63", 1 << 63),
        ("18446744073709551615", u64::MAX),
    ] {
        let l = Limits::parse(&format!("image_bytes={value}")).unwrap();
        assert_eq!(l.image_bytes, expected, "{value}");
        assert_eq!(l.get(Limit::ImageBytes), expected, "{value}");
    }
    // the scene hash's bound follows the largest file limit in effect
    assert_eq!(Limits::DEFAULT.input_file_bytes(), 8 << 30);
    assert_eq!(l_input("mesh_bytes=32G"), 32 << 30);
    assert_eq!(l_input("vol_bytes=1T,mesh_bytes=2^35"), 1 << 40);
    assert_eq!(
        l_input("image_bytes=1K,mesh_bytes=1K,vol_bytes=1K"),
        penumbra::io::MAX_SCENE_FILE_BYTES
    );
}

fn l_input(spec: &str) -> u64 {
    Limits::parse(spec).unwrap().input_file_bytes()
}

#[test]
fn malformed_values_are_refused_naming_the_variable_the_entry_and_the_limits() {
    let names = "the limits are render_pixels, image_pixels, image_bytes, mesh_bytes, \
                 shape_bytes, vol_bytes and radiosity_rays";
    for (spec, problem) in [
        (
            "mesh_byte=1K",
            "unknown limit \"mesh_byte\" in \"mesh_byte=1K\"",
        ),
        (
            "render_pixels=0",
            "a limit of 0 allows nothing in \"render_pixels=0\"",
        ),
        (
            "render_pixels=2^64",
            "value above 2^64 - 1 in \"render_pixels=2^64\"",
        ),
        ("render_pixels=1.5K", "bad value in \"render_pixels=1.5K\""),
        ("render_pixels=-4", "bad value in \"render_pixels=-4\""),
        ("render_pixels=4KB", "bad value in \"render_pixels=4KB\""),
        (
            "render_pixels",
            "no '=' (entries are name=value) in \"render_pixels\"",
        ),
        (
            "vol_bytes=1G,vol_bytes=2G",
            "vol_bytes given twice in \"vol_bytes=2G\"",
        ),
    ] {
        let e = Limits::parse(spec).expect_err(spec).to_string();
        assert!(
            e.starts_with(&format!(
                "PENUMBRA_LIMITS: {problem}; {names}, set as name=value"
            )),
            "{spec:?}: {e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}

// ---------------------------------------------------------------------------------------
// The variable, end to end
// ---------------------------------------------------------------------------------------

#[test]
fn a_malformed_variable_fails_in_one_line_before_anything_loads() {
    let dir = TempDir::new("malformed");
    // the scene does not exist: the variable is refused before the scene is looked at
    let out = render(&dir, &dir.path("missing.xml"), Some("mesh_bytes=8X"));
    let line = error_line(&out);
    assert!(
        line.starts_with(
            "error: PENUMBRA_LIMITS: bad value in \"mesh_bytes=8X\"; the limits are \
             render_pixels, image_pixels,"
        ),
        "{line}"
    );
    assert!(!line.contains("missing.xml"), "{line}");
    // every subcommand reads it first
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(["compare", "a.exr", "b.exr"])
        .env("PENUMBRA_LIMITS", "film_pixels=1")
        .current_dir(&dir.0)
        .output()
        .unwrap();
    let line = error_line(&out);
    assert!(
        line.starts_with(
            "error: PENUMBRA_LIMITS: unknown limit \"film_pixels\" in \"film_pixels=1\""
        ),
        "{line}"
    );
}

#[test]
fn a_film_above_a_lowered_render_pixels_limit_is_refused_and_renders_by_default() {
    let dir = TempDir::new("render-pixels");
    let xml = dir.write("scene.xml", scene(64, ""));
    // 64x64 = 4096 pixels, above 1024
    let line = error_line(&render(&dir, &xml, Some("render_pixels=1024")));
    assert!(
        line.starts_with(&format!("error: {}:", xml.display())),
        "{line}"
    );
    assert!(
        line.ends_with(
            "film of 64x64 pixels exceeds the render_pixels limit of 1024 pixels (raise it \
             with PENUMBRA_LIMITS=render_pixels=...)"
        ),
        "{line}"
    );
    // at the limit, and with the default (2^26)
    assert_renders(&render(&dir, &xml, Some("render_pixels=4096")));
    assert_renders(&render(&dir, &xml, None));
    // a raised limit admits a film above the default: refused without the variable (the
    // film is refused before anything is allocated for it, so this costs nothing)
    let big = dir.write(
        "big.xml",
        scene(65536, "").replace(
            r#"<integer name="height" value="65536"/>"#,
            r#"<integer name="height" value="1025"/>"#,
        ),
    );
    let line = error_line(&render(&dir, &big, None));
    assert!(
        line.ends_with(
            "film of 65536x1025 pixels exceeds the render_pixels limit of 67108864 pixels \
             (raise it with PENUMBRA_LIMITS=render_pixels=...)"
        ),
        "{line}"
    );
}

#[test]
fn a_mesh_file_above_a_lowered_mesh_bytes_limit_is_refused_and_loads_by_default() {
    let dir = TempDir::new("mesh-bytes");
    let ply = dir.write("grid.ply", grid_ply(8));
    let len = std::fs::metadata(&ply).unwrap().len();
    assert!(len > 1024, "the mesh must exceed 1 KiB: {len} bytes");
    let shape = format!(
        r#"<shape type="ply"><string name="filename" value="{}"/><bsdf type="diffuse"/></shape>"#,
        ply.display()
    );
    let xml = dir.write("scene.xml", scene(16, &shape));
    let line = error_line(&render(&dir, &xml, Some("mesh_bytes=1K")));
    assert!(
        line.ends_with(&format!(
            "{}: file of {len} bytes exceeds the mesh_bytes limit of 1 KiB (raise it with \
             PENUMBRA_LIMITS=mesh_bytes=...)",
            ply.display()
        )),
        "{line}"
    );
    // at the limit, and with the default (8 GiB)
    assert_renders(&render(&dir, &xml, Some(&format!("mesh_bytes={len}"))));
    assert_renders(&render(&dir, &xml, None));
    // another limit lowered leaves the mesh alone
    assert_renders(&render(&dir, &xml, Some("vol_bytes=1K,image_bytes=1K")));
}
