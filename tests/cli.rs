//! End-to-end tests of the `penumbra` binary: tiny renders of scenes written to a temporary
//! directory, and every kind of bad input ending in one `error:` line and exit status 1.

use penumbra::io::exr::{self, RgbImage};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const CORNELL: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/scenes/cornell-box.xml"
));

/// A temporary directory unique to this process and test, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("penumbra-cli-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `text` to `name` (creating parent directories) and returns its path.
    fn write(&self, name: &str, text: &str) -> PathBuf {
        let path = self.path(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, text).unwrap();
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The Cornell box with its film resolution replaced by the parameter `film_res`
/// (default 16), whatever the file says.
fn cornell() -> String {
    let mut text = CORNELL.to_string();
    for axis in ["width", "height"] {
        let start = format!(r#"<integer name="{axis}" value=""#);
        assert_eq!(text.matches(&start).count(), 1, "{start}");
        let begin = text.find(&start).unwrap() + start.len();
        let end = begin + text[begin..].find('"').unwrap();
        text.replace_range(begin..end, "$film_res");
    }
    let root = r#"<scene version="3.0.0">"#;
    assert_eq!(text.matches(root).count(), 1);
    text.replace(
        root,
        &format!("{root}\n    <default name=\"film_res\" value=\"16\"/>"),
    )
}

/// A 16x16 scene with a sensor looking down -z at `shapes` (and the path integrator, unless
/// `shapes` names one).
fn scene(shapes: &str) -> String {
    let integrator = if shapes.contains("<integrator") {
        ""
    } else {
        r#"<integrator type="path"/>"#
    };
    format!(
        r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world">
            <lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="16"/>
            <integer name="height" value="16"/>
            <rfilter type="box"/>
        </film>
    </sensor>
{shapes}
{integrator}
</scene>
"#
    )
}

/// Runs `penumbra` with `args`.
fn penumbra<I, S>(args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("cannot run penumbra")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn lines(out: &Output) -> Vec<String> {
    stderr(out).lines().map(str::to_string).collect()
}

fn assert_success(out: &Output) {
    assert_eq!(
        out.status.code(),
        Some(0),
        "penumbra failed: {}",
        stderr(out)
    );
}

/// Asserts that `out` is a clean failure: status 1, exactly one stderr line, starting with
/// `error:` and containing every one of `parts`, and nothing on stdout. Returns the line.
fn assert_error(out: &Output, parts: &[&str]) -> String {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!err.to_lowercase().contains("backtrace"), "{err}");
    assert!(!err.contains("Stack backtrace"), "{err}");
    assert!(err.ends_with('\n'), "{err:?}");
    let all: Vec<&str> = err.lines().collect();
    assert_eq!(all.len(), 1, "expected one line on stderr, got: {err}");
    let line = all[0];
    assert!(line.starts_with("error: "), "{line}");
    for part in parts {
        assert!(line.contains(part), "expected {part:?} in: {line}");
    }
    assert!(out.stdout.is_empty(), "{:?}", out.stdout);
    line.to_string()
}

/// Renders `scene` (a file in `dir`) with `extra` arguments and returns the failure output;
/// checks that no image was written.
fn render_fails(dir: &TempDir, scene: &Path, extra: &[&str]) -> Output {
    let exr = dir.path("out.exr");
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr.as_os_str(),
    ];
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    let out = penumbra(&args);
    assert!(!exr.exists(), "an image was written for a failing render");
    out
}

fn read_exr(path: &Path) -> RgbImage {
    exr::read(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

fn attribute<'a>(image: &'a RgbImage, name: &str) -> &'a str {
    image
        .attributes
        .get(name)
        .unwrap_or_else(|| panic!("no {name} in {:?}", image.attributes))
}

/// A PNG's size, from its IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
    (be(16), be(20))
}

// ---------------------------------------------------------------------------------------
// Successful renders
// ---------------------------------------------------------------------------------------

#[test]
fn renders_exr_and_preview() {
    let dir = TempDir::new("render");
    let scene = dir.write("cornell.xml", &cornell());
    let exr_path = dir.path("out.exr");
    let png_path = dir.path("preview.png");
    let out = penumbra([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "--spp".as_ref(),
        "2".as_ref(),
        "--seed".as_ref(),
        "7".as_ref(),
        "--preview".as_ref(),
        png_path.as_os_str(),
    ]);
    assert_success(&out);
    assert!(out.stdout.is_empty());
    let err = lines(&out);
    assert_eq!(err.len(), 1, "one summary line expected: {err:?}");
    let summary = &err[0];
    assert!(summary.starts_with("16x16, 2 spp, "), "{summary}");
    assert!(summary.contains(" Mpath/s, "), "{summary}");
    assert!(
        summary.contains("0 non-finite samples dropped"),
        "{summary}"
    );
    assert!(
        summary.ends_with(&format!("-> {}", exr_path.display())),
        "{summary}"
    );

    let image = read_exr(&exr_path);
    assert_eq!((image.width, image.height), (16, 16));
    assert_eq!(image.rgb.len(), 256);
    assert_eq!(image.variance, None);
    assert_eq!(attribute(&image, "spp"), "2");
    assert_eq!(attribute(&image, "seed"), "7");
    assert_eq!(
        attribute(&image, "penumbra_version"),
        env!("CARGO_PKG_VERSION")
    );
    assert_eq!(attribute(&image, "nonfinite_samples"), "0");
    let seconds: f64 = attribute(&image, "render_time_seconds").parse().unwrap();
    assert!(seconds >= 0.0 && seconds.is_finite(), "{seconds}");
    assert!(image
        .rgb
        .iter()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
    // The box is lit: most pixels see something.
    let lit = image
        .rgb
        .iter()
        .filter(|p| p.iter().sum::<f32>() > 0.0)
        .count();
    assert!(lit > 128, "only {lit} lit pixels");
    // No temporary file is left behind by the atomic write.
    assert!(!dir.path(".out.exr.tmp").exists());

    assert_eq!(png_size(&png_path), (16, 16));
}

#[test]
fn scene_sample_count_and_seed_are_defaults() {
    let dir = TempDir::new("scene-spp");
    let scene = dir.write("cornell.xml", &cornell());
    let exr_path = dir.path("out.exr");
    // The Cornell box's sample_count is $spp (64): override it with -D, not --spp.
    let out = penumbra([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "-D".as_ref(),
        "spp=3".as_ref(),
        "-D".as_ref(),
        "film_res=8".as_ref(),
    ]);
    assert_success(&out);
    let err = lines(&out);
    assert_eq!(err.len(), 1, "{err:?}");
    assert!(err[0].starts_with("8x8, 3 spp, "), "{}", err[0]);
    let image = read_exr(&exr_path);
    assert_eq!((image.width, image.height), (8, 8));
    assert_eq!(attribute(&image, "spp"), "3");
    assert_eq!(attribute(&image, "seed"), "0");
}

#[test]
fn quiet_prints_nothing() {
    let dir = TempDir::new("quiet");
    let scene = dir.write("cornell.xml", &cornell());
    let exr_path = dir.path("out.exr");
    let out = penumbra([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "--spp".as_ref(),
        "1".as_ref(),
        "--quiet".as_ref(),
    ]);
    assert_success(&out);
    assert_eq!(stderr(&out), "");
    assert!(out.stdout.is_empty());
    let image = read_exr(&exr_path);
    assert_eq!((image.width, image.height), (16, 16));
    assert_eq!(attribute(&image, "spp"), "1");
}

#[test]
fn variance_channels() {
    let dir = TempDir::new("variance");
    let scene = dir.write("cornell.xml", &cornell());
    let exr_path = dir.path("out.exr");
    let out = penumbra([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "--spp".as_ref(),
        "4".as_ref(),
        "--variance".as_ref(),
        "--quiet".as_ref(),
    ]);
    assert_success(&out);
    let image = read_exr(&exr_path);
    let variance = image.variance.expect("no variance channels");
    assert_eq!(variance.len(), 256);
    assert!(variance
        .iter()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
    // Four samples of a path-traced Cornell box do not all agree everywhere.
    assert!(variance.iter().flatten().any(|v| *v > 0.0));
}

/// The variance channels are the variance of one sample (box filter: spp × the variance of
/// the pixel value), checked against independent truth: the empirical variance of the pixel
/// values over 16 seeds (issue 44: an inflated variance passed the test above, and it makes
/// every z-test easier). Per pixel, d = Σ_c (empirical variance − mean over seeds of
/// variance / spp); both are unbiased, so E[d] = 0, and over the 256 pixels (independent:
/// their samples are) z = mean(d) / (sd(d) / √256) is within ±3.29 (two-sided p = 0.001).
/// Seen: z = −0.93 as is; an estimate 20% too large gives z = −7.7, 20% too small +6.5.
#[test]
fn variance_channels_match_the_variance_across_seeds() {
    let dir = TempDir::new("variance-seeds");
    // Every pixel sees the same diffuse plane under a uniform sky, lit directly: the same
    // distribution of samples at every pixel, so the 256 pixels are exchangeable.
    let scene = dir.write(
        "sky.xml",
        &scene(
            r#"<shape type="rectangle"><transform name="to_world"><scale value="10"/></transform><bsdf type="diffuse"/></shape>
               <emitter type="constant"/>
               <integrator type="path"><integer name="max_depth" value="2"/></integrator>"#,
        ),
    );
    let (seeds, spp) = (16, 4);
    let mut values: Vec<Vec<[f32; 3]>> = Vec::new();
    let mut predicted = vec![[0.0f64; 3]; 256];
    for seed in 0..seeds {
        let exr_path = dir.path(&format!("s{seed}.exr"));
        let out = penumbra([
            "render".as_ref(),
            scene.as_os_str(),
            "-o".as_ref(),
            exr_path.as_os_str(),
            "--spp".as_ref(),
            spp.to_string().as_ref(),
            "--seed".as_ref(),
            seed.to_string().as_ref(),
            "--variance".as_ref(),
            "--quiet".as_ref(),
        ]);
        assert_success(&out);
        let image = read_exr(&exr_path);
        let variance = image.variance.expect("no variance channels");
        for (p, v) in predicted.iter_mut().zip(&variance) {
            for c in 0..3 {
                p[c] += v[c] as f64 / spp as f64 / seeds as f64;
            }
        }
        values.push(image.rgb);
    }
    let d: Vec<f64> = (0..256)
        .map(|i| {
            (0..3)
                .map(|c| {
                    let x: Vec<f64> = values.iter().map(|v| v[i][c] as f64).collect();
                    let mean = x.iter().sum::<f64>() / seeds as f64;
                    let empirical =
                        x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (seeds - 1) as f64;
                    empirical - predicted[i][c]
                })
                .sum()
        })
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let z = mean / (sd / n.sqrt());
    let total: f64 = predicted.iter().flatten().sum();
    assert!(total > 0.0);
    assert!(
        z.abs() < 3.29,
        "variance channels vs the variance across seeds: z = {z:.2} (mean difference {mean:.3e}, \
         mean predicted per pixel {:.3e})",
        total / 256.0
    );
}

#[test]
fn same_seed_same_image_at_any_thread_count() {
    let dir = TempDir::new("determinism");
    let scene = dir.write("cornell.xml", &cornell());
    let render = |name: &str, threads: &str, seed: &str| {
        let path = dir.path(name);
        let out = penumbra([
            "render".as_ref(),
            scene.as_os_str(),
            "-o".as_ref(),
            path.as_os_str(),
            "--spp".as_ref(),
            "2".as_ref(),
            "--seed".as_ref(),
            seed.as_ref(),
            "--threads".as_ref(),
            threads.as_ref(),
            "--quiet".as_ref(),
        ]);
        assert_success(&out);
        read_exr(&path).rgb
    };
    let one = render("one.exr", "1", "5");
    let three = render("three.exr", "3", "5");
    assert_eq!(one, three);
    let other_seed = render("other.exr", "1", "6");
    assert_ne!(one, other_seed);
}

#[test]
fn defines_need_an_equals_sign() {
    let dir = TempDir::new("define");
    let scene = dir.write("cornell.xml", &cornell());
    let out = render_fails(&dir, &scene, &["-D", "spp"]);
    assert_error(&out, &["-D expects NAME=VALUE, got 'spp'"]);
    let out = render_fails(&dir, &scene, &["-D", "=3"]);
    assert_error(&out, &["-D expects NAME=VALUE, got '=3'"]);
}

#[test]
fn obj_with_bad_faces_renders_with_a_warning() {
    let dir = TempDir::new("obj");
    // One good triangle, one with a NaN vertex, one degenerate (collinear) one.
    dir.write(
        "meshes/tri.obj",
        "v -1 -1 0\nv 1 -1 0\nv -1 1 0\nv nan 0 0\nv 0 -1 0\n\
         f 1 2 3\nf 4 2 3\nf 1 5 2\n",
    );
    let scene_path = dir.write(
        "scene.xml",
        &scene(
            r#"<shape type="obj">
        <string name="filename" value="meshes/tri.obj"/>
        <emitter type="area"><rgb name="radiance" value="1"/></emitter>
    </shape>"#,
        ),
    );
    let exr_path = dir.path("out.exr");
    let out = penumbra([
        "render".as_ref(),
        scene_path.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "--spp".as_ref(),
        "1".as_ref(),
    ]);
    assert_success(&out);
    let err = lines(&out);
    assert_eq!(err.len(), 2, "a warning and the summary expected: {err:?}");
    let mesh = dir.path("meshes/tri.obj");
    assert_eq!(
        err[0],
        format!(
            "warning: {}: skipped 2 degenerate or non-finite face(s)",
            mesh.display()
        )
    );
    assert!(err[1].contains("Mpath/s"), "{}", err[1]);
    // The remaining triangle faces the camera and emits 1: the centre pixel sees it.
    let image = read_exr(&exr_path);
    assert_eq!((image.width, image.height), (16, 16));
    assert!(image.rgb.iter().flatten().all(|v| v.is_finite()));
    assert_eq!(
        image.rgb[7 * 16 + 8],
        [0.0; 3],
        "upper right of the diagonal"
    );
    assert!(image.rgb.contains(&[1.0; 3]));
}

#[test]
fn scene_without_emitter_is_black_with_a_warning() {
    let dir = TempDir::new("no-emitter");
    let scene_path = dir.write("scene.xml", &scene(r#"<shape type="sphere"/>"#));
    let exr_path = dir.path("out.exr");
    let out = penumbra([
        "render".as_ref(),
        scene_path.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "--spp".as_ref(),
        "2".as_ref(),
    ]);
    assert_success(&out);
    let err = lines(&out);
    assert_eq!(err.len(), 2, "{err:?}");
    assert_eq!(
        err[0],
        "warning: the scene has no emitter: the image will be black"
    );
    assert!(err[1].contains("Mpath/s"), "{}", err[1]);
    let image = read_exr(&exr_path);
    assert_eq!((image.width, image.height), (16, 16));
    assert!(image.rgb.iter().all(|p| *p == [0.0; 3]));
}

// ---------------------------------------------------------------------------------------
// Bad input: one `error:` line, status 1, no panic
// ---------------------------------------------------------------------------------------

#[test]
fn missing_scene_file() {
    let dir = TempDir::new("missing");
    let scene = dir.path("nope.xml");
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[&scene.display().to_string(), "No such file or directory"],
    );
}

#[test]
fn directory_as_scene() {
    let dir = TempDir::new("directory");
    let scene = dir.path("a-directory.xml");
    std::fs::create_dir_all(&scene).unwrap();
    let out = render_fails(&dir, &scene, &[]);
    assert_error(&out, &[&scene.display().to_string(), "directory"]);
}

/// I/O errors name the file and the OS's reason once: `error: PATH: REASON (os error N)`.
#[test]
fn io_error_messages_do_not_repeat_their_cause() {
    let dir = TempDir::new("io-once");
    let missing = dir.path("nope.xml");
    let out = render_fails(&dir, &missing, &[]);
    let line = assert_error(&out, &[]);
    assert_eq!(
        line,
        format!(
            "error: {}: No such file or directory (os error 2)",
            missing.display()
        )
    );
    let directory = dir.path("a-directory.xml");
    std::fs::create_dir_all(&directory).unwrap();
    let out = render_fails(&dir, &directory, &[]);
    let line = assert_error(&out, &[]);
    assert_eq!(
        line,
        format!(
            "error: {}: is a directory, not a regular file",
            directory.display()
        )
    );
    let scene = dir.write(
        "scene.xml",
        &scene(
            r#"    <shape type="obj">
        <string name="filename" value="missing.obj"/>
    </shape>"#,
        ),
    );
    let out = render_fails(&dir, &scene, &[]);
    let line = assert_error(&out, &[]);
    assert_eq!(
        line,
        format!(
            "error: {}: No such file or directory (os error 2)",
            dir.path("missing.obj").display()
        )
    );
}

#[test]
fn malformed_xml() {
    let dir = TempDir::new("malformed");
    let scene = dir.write(
        "scene.xml",
        "<scene version=\"3.0.0\">\n<shape type=\"sphere\">\n</scene>\n",
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(&out, &[&format!("{}: malformed XML", scene.display())]);
    let scene = dir.write("garbage.xml", "this is not XML at all");
    let out = render_fails(&dir, &scene, &[]);
    assert_error(&out, &[&format!("{}: malformed XML", scene.display())]);
}

#[test]
fn truncated_xml() {
    let dir = TempDir::new("truncated");
    let text = cornell();
    for cut in [text.len() / 3, text.len() / 2, text.len() - 10] {
        let scene = dir.write("scene.xml", &text[..cut]);
        let out = render_fails(&dir, &scene, &[]);
        assert_error(&out, &[&format!("{}: malformed XML", scene.display())]);
    }
}

#[test]
fn non_utf8_scene() {
    let dir = TempDir::new("utf8");
    let scene = dir.path("scene.xml");
    // (Mitsuba, like pugixml, passes invalid bytes in text through; in an attribute value
    // penumbra needs text and refuses them)
    std::fs::write(
        &scene,
        b"<scene version=\"3.0.0\">\n<shape type=\"\xff\xfe\"/></scene>\n",
    )
    .unwrap();
    let out = render_fails(&dir, &scene, &[]);
    assert_error(&out, &["not valid UTF-8", "line 2"]);
}

/// A one-sphere scene whose sphere has the extra `property` on line 14, with an emitter so
/// that the scene is otherwise valid.
fn sphere_scene(property: &str) -> String {
    let text = scene(&format!(
        r#"    <shape type="sphere">
        {property}
        <emitter type="area"><rgb name="radiance" value="1"/></emitter>
    </shape>"#
    ));
    assert_eq!(
        text.lines().nth(13).map(str::trim),
        Some(property),
        "{text}"
    );
    text
}

#[test]
fn unknown_plugin() {
    let dir = TempDir::new("plugin");
    let scene = dir.write("scene.xml", &sphere_scene(r#"<bsdf type="hair"/>"#));
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[
            &format!("{}:14:", scene.display()),
            "unsupported plugin <bsdf type=\"hair\">",
        ],
    );
}

#[test]
fn unknown_parameter() {
    let dir = TempDir::new("parameter");
    let scene = dir.write(
        "scene.xml",
        &sphere_scene(r#"<float name="radiuss" value="2"/>"#),
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[
            &format!("{}:14:", scene.display()),
            "unknown parameter 'radiuss' (float) of <shape type=\"sphere\">",
        ],
    );
}

#[test]
fn unparsable_number() {
    let dir = TempDir::new("nan-text");
    let scene = dir.write(
        "scene.xml",
        &sphere_scene(r#"<float name="radius" value="abc"/>"#),
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[
            &format!("{}:14:", scene.display()),
            "could not parse floating point value \"abc\"",
            "<float name=\"radius\">",
        ],
    );
    let scene = dir.write(
        "scene.xml",
        &sphere_scene(r#"<integer name="radius" value="2.5x"/>"#),
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[
            &format!("{}:14:", scene.display()),
            "could not parse integer value \"2.5x\"",
        ],
    );
}

#[test]
fn non_finite_numbers() {
    let dir = TempDir::new("non-finite");
    for value in ["nan", "1e999", "-inf", "NaN"] {
        let scene = dir.write(
            "scene.xml",
            &sphere_scene(&format!(r#"<float name="radius" value="{value}"/>"#)),
        );
        let out = render_fails(&dir, &scene, &[]);
        assert_error(
            &out,
            &[
                &format!("{}:14:", scene.display()),
                &format!("non-finite floating point value \"{value}\""),
            ],
        );
    }
    let scene = dir.write(
        "scene.xml",
        &sphere_scene(r#"<point name="center" value="0, 1e999, 0"/>"#),
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[
            &format!("{}:14:", scene.display()),
            "non-finite floating point value \"1e999\"",
        ],
    );
}

#[test]
fn missing_mesh_file() {
    let dir = TempDir::new("missing-mesh");
    let scene = dir.write(
        "scene.xml",
        &scene(
            r#"    <shape type="obj">
        <string name="filename" value="meshes/missing.obj"/>
    </shape>"#,
        ),
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[
            &dir.path("meshes/missing.obj").display().to_string(),
            "No such file or directory",
        ],
    );
}

#[test]
fn broken_mesh_file() {
    let dir = TempDir::new("broken-mesh");
    dir.write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    let scene = dir.write(
        "scene.xml",
        &scene(
            r#"    <shape type="obj">
        <string name="filename" value="bad.obj"/>
    </shape>"#,
        ),
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(
        &out,
        &[&format!(
            "{}: cannot load mesh:",
            dir.path("bad.obj").display()
        )],
    );
}

#[test]
fn cyclic_includes() {
    let dir = TempDir::new("cycle");
    let a = dir.write(
        "a.xml",
        r#"<scene version="3.0.0">
    <include filename="b.xml"/>
</scene>
"#,
    );
    dir.write(
        "b.xml",
        r#"<scene version="3.0.0">
    <include filename="a.xml"/>
</scene>
"#,
    );
    let out = render_fails(&dir, &a, &[]);
    assert_error(
        &out,
        &[
            &format!("{}:2:", dir.path("b.xml").display()),
            "cyclic include",
        ],
    );
    // A file including itself.
    let selfish = dir.write(
        "self.xml",
        r#"<scene version="3.0.0">
    <include filename="self.xml"/>
</scene>
"#,
    );
    let out = render_fails(&dir, &selfish, &[]);
    assert_error(
        &out,
        &[&format!("{}:2:", selfish.display()), "cyclic include"],
    );
}

#[test]
fn zero_resolution() {
    let dir = TempDir::new("zero-res");
    let scene = dir.write("cornell.xml", &cornell());
    let out = render_fails(&dir, &scene, &["-D", "film_res=0"]);
    assert_error(
        &out,
        &[
            &scene.display().to_string(),
            "film width must be between 1 and 65536, got 0",
        ],
    );
    let out = render_fails(&dir, &scene, &["-D", "film_res=1000000000"]);
    assert_error(
        &out,
        &["film width must be between 1 and 65536, got 1000000000"],
    );
}

#[test]
fn zero_spp() {
    let dir = TempDir::new("zero-spp");
    let scene = dir.write("cornell.xml", &cornell());
    let out = render_fails(&dir, &scene, &["--spp", "0"]);
    let line = assert_error(&out, &[]);
    assert_eq!(line, "error: --spp must be at least 1");
}

#[test]
fn zero_threads() {
    let dir = TempDir::new("zero-threads");
    let scene = dir.write("cornell.xml", &cornell());
    let out = render_fails(&dir, &scene, &["--threads", "0", "--spp", "1"]);
    let line = assert_error(&out, &[]);
    assert_eq!(line, "error: --threads must be at least 1");
}

#[test]
fn no_sensor() {
    let dir = TempDir::new("no-sensor");
    let scene = dir.write(
        "scene.xml",
        "<scene version=\"3.0.0\">\n    <shape type=\"sphere\"/>\n</scene>\n",
    );
    let out = render_fails(&dir, &scene, &[]);
    assert_error(&out, &["no <sensor>"]);
}

#[test]
fn unwritable_output() {
    let dir = TempDir::new("unwritable");
    let scene = dir.write("cornell.xml", &cornell());
    let exr_path = dir.path("no/such/dir/out.exr");
    let out = penumbra([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "--spp".as_ref(),
        "1".as_ref(),
        "--quiet".as_ref(),
    ]);
    assert_error(
        &out,
        &[&format!("{}: cannot write image", exr_path.display())],
    );
}

/// Mitsuba's integrator `timeout` (seconds) is the render's time limit when the command line
/// gives none: a render of a million samples per pixel with a timeout of 0 stops after its
/// first pass.
#[test]
fn the_integrators_timeout_is_the_time_limit() {
    let dir = TempDir::new("timeout");
    let body = r#"<integrator type="path"><float name="timeout" value="0"/></integrator>
<shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#;
    let scene = dir.write("timeout.xml", &scene(body));
    let exr_path = dir.path("out.exr");
    let out = penumbra([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr_path.as_os_str(),
        "--spp".as_ref(),
        "1000000".as_ref(),
    ]);
    assert_success(&out);
    let err = stderr(&out);
    assert!(err.contains("stopped: time limit"), "{err}");
    assert!(err.contains("16x16, 256 spp"), "{err}");
}
