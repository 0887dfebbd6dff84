//! Issue 40: every read is bounded before it allocates, and an error never quotes what a
//! file holds. Each hostile input here goes through the `penumbra` binary and must end,
//! within a time limit, in exactly one `error:` line (or, for the library-level cases, one
//! `Error`), never a panic, a hang or an unbounded allocation.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A temporary directory unique to this process and test, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("penumbra-hostile-{}-{test}", std::process::id()));
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

/// Runs `penumbra args` and returns its status code and stderr; kills it and fails the test
/// if it has not ended after `limit` (a hang must fail, not block the suite).
fn penumbra_within(dir: &TempDir, args: &[&std::ffi::OsStr], limit: Duration) -> (i32, String) {
    let (out, err) = (dir.path("stdout.txt"), dir.path("stderr.txt"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .expect("cannot run penumbra");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > limit {
            child.kill().ok();
            child.wait().ok();
            panic!(
                "penumbra {args:?} still running after {limit:?} (killed); stderr so far: {}",
                std::fs::read_to_string(&err).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stdout = std::fs::read(&out).unwrap();
    assert!(
        stdout.is_empty(),
        "stdout: {}",
        String::from_utf8_lossy(&stdout)
    );
    let stderr = String::from_utf8_lossy(&std::fs::read(&err).unwrap()).into_owned();
    (status.code().unwrap_or(-1), stderr)
}

/// Asserts a clean failure: status 1 and exactly one stderr line, `error: ...`, containing
/// every one of `parts`. Returns the line.
fn one_error_line(code: i32, stderr: &str, parts: &[&str]) -> String {
    assert_eq!(code, 1, "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "expected one line on stderr, got: {stderr}");
    let line = lines[0];
    assert!(line.starts_with("error: "), "{line}");
    for part in parts {
        assert!(line.contains(part), "expected {part:?} in: {line}");
    }
    // What penumbra says, for `cargo test --test hostile_files -- --nocapture`.
    eprintln!("penumbra said: {line}");
    line.to_string()
}

/// `penumbra render scene -o dir/out.exr` must fail within `limit` with one error line
/// containing `parts`; returns the line.
fn render_refused(dir: &TempDir, scene: &Path, limit: Duration, parts: &[&str]) -> String {
    let exr = dir.path("out.exr");
    let args = [
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        exr.as_os_str(),
    ];
    let (code, stderr) = penumbra_within(dir, &args, limit);
    let line = one_error_line(code, &stderr, parts);
    assert!(!exr.exists(), "an image was written for a failing render");
    line
}

/// A 4x4 scene around `shapes`, with an integrator (none is a warning, a second line).
fn scene(shapes: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"/>
    <sensor type="perspective">
        <film type="hdrfilm">
            <integer name="width" value="4"/>
            <integer name="height" value="4"/>
        </film>
    </sensor>
    <emitter type="constant"/>
{shapes}
</scene>
"#
    )
}

fn mesh(plugin: &str, filename: &Path) -> String {
    format!(
        r#"<shape type="{plugin}"><string name="filename" value="{}"/></shape>"#,
        filename.display()
    )
}

// ---------------------------------------------------------------------------------------
// 1. Special files: the scene's identity hash and every loader refuse them before reading
// ---------------------------------------------------------------------------------------

#[test]
fn a_mesh_that_is_dev_zero_is_refused_at_once() {
    let dir = TempDir::new("dev-zero");
    for plugin in ["obj", "ply", "serialized"] {
        let xml = dir.write("scene.xml", scene(&mesh(plugin, Path::new("/dev/zero"))));
        let line = render_refused(&dir, &xml, Duration::from_secs(10), &[]);
        assert_eq!(line, "error: /dev/zero: is a device, not a regular file");
    }
}

#[cfg(unix)]
#[test]
fn a_mesh_that_is_a_fifo_is_refused_without_blocking() {
    let dir = TempDir::new("fifo");
    let fifo = dir.path("mesh.ply");
    match Command::new("mkfifo").arg(&fifo).status() {
        Ok(s) => assert!(s.success(), "mkfifo failed"),
        Err(_) => {
            eprintln!("mkfifo is not installed: skipped");
            return;
        }
    }
    // Nobody ever writes to the FIFO: opening it to read would wait forever.
    let xml = dir.write("scene.xml", scene(&mesh("ply", &fifo)));
    let line = render_refused(&dir, &xml, Duration::from_secs(10), &[]);
    assert_eq!(
        line,
        format!("error: {}: is a FIFO, not a regular file", fifo.display())
    );
}

/// Checkpoint and part files are read as bounded regular files too: `merge` of a part that
/// is /dev/zero or a FIFO (which used to read forever, or wait forever for a writer).
#[cfg(unix)]
#[test]
fn a_part_file_that_is_dev_zero_or_a_fifo_is_refused_without_blocking() {
    let dir = TempDir::new("part-special");
    let fifo = dir.path("part.pnbr");
    match Command::new("mkfifo").arg(&fifo).status() {
        Ok(s) => assert!(s.success(), "mkfifo failed"),
        Err(_) => {
            eprintln!("mkfifo is not installed: skipped");
            return;
        }
    }
    let out = dir.path("merged.exr");
    for (part, what) in [
        (Path::new("/dev/zero"), "a device"),
        (fifo.as_path(), "a FIFO"),
    ] {
        let args = [
            "merge".as_ref(),
            part.as_os_str(),
            "-o".as_ref(),
            out.as_os_str(),
        ];
        let (code, stderr) = penumbra_within(&dir, &args, Duration::from_secs(10));
        let line = one_error_line(code, &stderr, &[&format!("is {what}, not a regular file")]);
        assert!(line.contains(&part.display().to_string()), "{line}");
        assert!(!out.exists(), "an image was written for a failed merge");
    }
}

// ---------------------------------------------------------------------------------------
// 2. OpenEXR input (references, `compare`, `report`): size and layout checked first
// ---------------------------------------------------------------------------------------

/// A small RGB EXR as penumbra writes it.
fn small_exr(path: &Path) {
    let image = penumbra::io::exr::RgbImage {
        width: 4,
        height: 4,
        rgb: (0..16).map(|i| [i as f32, 0.5, 0.25]).collect(),
        variance: None,
        attributes: Default::default(),
    };
    penumbra::io::exr::write(path, &image, &[]).unwrap();
}

/// The offset of the value of header attribute `name` of type `ty` (after its size).
fn attribute_value(bytes: &[u8], name: &str, ty: &str) -> usize {
    let key = [name.as_bytes(), b"\0", ty.as_bytes(), b"\0"].concat();
    let at = bytes
        .windows(key.len())
        .position(|w| w == key.as_slice())
        .unwrap_or_else(|| panic!("no {name} attribute"));
    at + key.len() + 4
}

fn put_i32(bytes: &mut [u8], at: usize, v: i32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// `penumbra compare crafted good` must fail with one line containing `parts`.
fn compare_refused(dir: &TempDir, crafted: &Path, parts: &[&str]) -> String {
    let good = dir.path("good.exr");
    small_exr(&good);
    let args = ["compare".as_ref(), crafted.as_os_str(), good.as_os_str()];
    let (code, stderr) = penumbra_within(dir, &args, Duration::from_secs(10));
    one_error_line(code, &stderr, parts)
}

#[test]
fn an_exr_whose_data_window_is_huge_is_refused_before_allocating() {
    let dir = TempDir::new("exr-window");
    let good = dir.path("small.exr");
    small_exr(&good);
    let bytes = std::fs::read(&good).unwrap();
    let window = attribute_value(&bytes, "dataWindow", "box2i");
    // 65536 x 65536 pixels: 2^32, above the pixel limit
    let mut huge = bytes.clone();
    put_i32(&mut huge, window + 8, 65535);
    put_i32(&mut huge, window + 12, 65535);
    let path = dir.write("huge.exr", &huge);
    let line = compare_refused(&dir, &path, &[]);
    assert_eq!(
        line,
        format!(
            "error: {}: cannot read image: image of 65536 x 65536 pixels exceeds the \
             image_pixels limit of 268435456 pixels (raise it with \
             PENUMBRA_LIMITS=image_pixels=...)",
            path.display()
        )
    );
    // 16384 x 16384 (within the pixel limit) of three float channels: 3 GiB from a file of
    // a few hundred bytes, which no EXR compression can hold
    let mut lying = bytes;
    put_i32(&mut lying, window + 8, 16383);
    put_i32(&mut lying, window + 12, 16383);
    let path = dir.write("lying.exr", &lying);
    let line = compare_refused(
        &dir,
        &path,
        &["cannot read image: header claims 16384 x 16384"],
    );
    assert!(line.ends_with("-byte file can hold"), "{line}");
}

#[test]
fn an_exr_with_a_subsampled_channel_is_refused() {
    let dir = TempDir::new("exr-subsampled");
    let good = dir.path("small.exr");
    small_exr(&good);
    let mut bytes = std::fs::read(&good).unwrap();
    // the channel list: per channel its name, NUL, type, pLinear + 3 reserved bytes, then
    // x and y sampling; the first channel ("B") gets a sampling of 2 x 2
    let list = attribute_value(&bytes, "channels", "chlist");
    assert_eq!(&bytes[list..list + 2], b"B\0");
    put_i32(&mut bytes, list + 2 + 8, 2);
    put_i32(&mut bytes, list + 2 + 12, 2);
    let path = dir.write("subsampled.exr", &bytes);
    let line = compare_refused(&dir, &path, &[]);
    assert_eq!(
        line,
        format!(
            "error: {}: cannot read image: sub-sampled OpenEXR channels are not supported",
            path.display()
        )
    );
    // the library refuses it too (the Python module and the report read it so)
    let e = penumbra::io::exr::read(&path).unwrap_err();
    assert!(e.to_string().contains("sub-sampled"), "{e}");
}

// ---------------------------------------------------------------------------------------
// 3. `<include>` fan-out: the included files parsed for one scene are bounded in number
//    and bytes, not only in depth
// ---------------------------------------------------------------------------------------

/// Files `f0.xml` ... `f{levels-1}.xml`, each including the next `fanout` times; `f0.xml`
/// is the scene.
fn include_chain(dir: &TempDir, levels: usize, fanout: usize) -> PathBuf {
    for i in 0..levels {
        let includes = if i + 1 < levels {
            format!("<include filename=\"f{}.xml\"/>\n", i + 1).repeat(fanout)
        } else {
            String::new()
        };
        let text = if i == 0 {
            scene(&includes)
        } else {
            format!("<scene version=\"3.0.0\">\n{includes}</scene>\n")
        };
        dir.write(&format!("f{i}.xml"), text);
    }
    dir.path("f0.xml")
}

#[test]
fn files_that_each_include_the_next_twice_stop_at_the_include_budget() {
    let dir = TempDir::new("include-twice");
    // 14 levels (the main file and 13 below it: Mitsuba's depth limit is 15 files) of two
    // includes each: 2^14 - 2 included files if nothing stopped it
    let main = include_chain(&dir, 14, 2);
    let start = Instant::now();
    render_refused(
        &dir,
        &main,
        Duration::from_secs(10),
        &["more than 8192 included files parsed for one scene"],
    );
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{:?}",
        start.elapsed()
    );
    // the same chain 30 files deep stops at the depth limit on its way down
    let dir = TempDir::new("include-deep");
    let main = include_chain(&dir, 30, 2);
    render_refused(
        &dir,
        &main,
        Duration::from_secs(10),
        &["exceeds the include depth limit of 15 files"],
    );
}

#[test]
fn files_that_each_include_the_next_eight_times_fail_fast() {
    // 8^13 included files without the budget: the render would never start
    let dir = TempDir::new("include-eight");
    let main = include_chain(&dir, 14, 8);
    render_refused(
        &dir,
        &main,
        Duration::from_secs(10),
        &["more than 8192 included files parsed for one scene"],
    );
}

#[test]
fn a_scene_may_include_one_file_many_times_within_the_budget() {
    // 1000 includes of a small file: far from the budget, the scene renders
    let dir = TempDir::new("include-many");
    dir.write(
        "part.xml",
        "<scene version=\"3.0.0\"><shape type=\"sphere\"/></scene>\n",
    );
    let main = dir.write(
        "main.xml",
        scene(&"<include filename=\"part.xml\"/>\n".repeat(1000)),
    );
    let exr = dir.path("out.exr");
    let args = [
        "render".as_ref(),
        main.as_os_str(),
        "-o".as_ref(),
        exr.as_os_str(),
    ];
    let (code, stderr) = penumbra_within(&dir, &args, Duration::from_secs(60));
    assert_eq!(code, 0, "{stderr}");
    assert!(exr.exists());
}

#[test]
fn the_xml_parsed_for_one_scene_is_bounded_in_bytes() {
    // a 70 MiB file (a comment) included 16 times: 1.1 GiB of XML, above the 1 GiB budget
    let dir = TempDir::new("include-bytes");
    let mut big = b"<scene version=\"3.0.0\"><!-- ".to_vec();
    big.resize(big.len() + (70 << 20), b'x');
    big.extend_from_slice(b" --></scene>\n");
    dir.write("big.xml", big);
    let main = dir.write(
        "main.xml",
        scene(&"<include filename=\"big.xml\"/>\n".repeat(16)),
    );
    render_refused(
        &dir,
        &main,
        Duration::from_secs(30),
        &["more than 1073741824 bytes of XML parsed for one scene"],
    );
}

// ---------------------------------------------------------------------------------------
// 4. `serialized` meshes: the decompressed size is bounded before inflating
// ---------------------------------------------------------------------------------------

/// A version-4 `.serialized` file of one shape whose header claims `vertices` and `faces`
/// (flags `flags`) and whose zlib stream really inflates to 1 GiB of zeros, from about
/// 1 MiB: the header, then 64 deflate pieces of 16 MiB of zeros each. Each piece ends in a
/// sync flush (byte-aligned) and refers only to the zeros before it, so one piece repeated
/// is a valid stream.
fn serialized_bomb(flags: u32, vertices: u64, faces: u64) -> Vec<u8> {
    use std::io::Write;
    let zeros = vec![0u8; 16 << 20];
    let mut shape = Vec::new();
    shape.extend_from_slice(&flags.to_le_bytes());
    shape.extend_from_slice(b"bomb\0");
    shape.extend_from_slice(&vertices.to_le_bytes());
    shape.extend_from_slice(&faces.to_le_bytes());
    let mut deflate = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
    deflate.write_all(&shape).unwrap();
    deflate.write_all(&zeros).unwrap();
    deflate.flush().unwrap();
    let first = deflate.get_ref().len();
    deflate.write_all(&zeros).unwrap();
    deflate.flush().unwrap();
    let (head, piece) = deflate.get_ref().split_at(first);
    // magic 0x041C, version 4, a zlib header (best compression), the deflate stream
    let mut file = vec![0x1c, 0x04, 0x04, 0x00, 0x78, 0xda];
    file.extend_from_slice(head);
    // the pieces really are a stream of zeros: three of them inflate to 48 MiB more
    let mut probe = file[4..].to_vec();
    probe.extend_from_slice(&piece.repeat(3));
    let mut inflated = Vec::new();
    let _ = std::io::Read::read_to_end(
        &mut flate2::read::ZlibDecoder::new(&probe[..]),
        &mut inflated,
    );
    assert_eq!(inflated.len(), shape.len() + 4 * zeros.len());
    assert!(inflated[shape.len()..].iter().all(|&b| b == 0));
    file.extend_from_slice(&piece.repeat(63));
    // the shape table: offset 0, one shape
    file.extend_from_slice(&0u64.to_le_bytes());
    file.extend_from_slice(&1u32.to_le_bytes());
    file
}

#[test]
fn a_serialized_decompression_bomb_is_refused_before_inflating() {
    let dir = TempDir::new("serialized-bomb");
    // 2^28 single-precision vertices (3 GiB of positions) and no triangle: within the size
    // limit, but 1 MiB of deflate data cannot hold it (it inflates to 1 GiB, then ends)
    let bomb = serialized_bomb(0x1000, 1 << 28, 0);
    assert!(bomb.len() < 2 << 20, "{} bytes", bomb.len());
    let path = dir.write("bomb.serialized", &bomb);
    let xml = dir.write("scene.xml", scene(&mesh("serialized", &path)));
    let start = Instant::now();
    let line = render_refused(&dir, &xml, Duration::from_secs(10), &[]);
    assert_eq!(
        line,
        format!(
            "error: {}: cannot load mesh: shape 0: 268435456 vertices and 0 triangles need \
             3221225472 bytes, more than {} compressed bytes can hold (deflate expands at \
             most 1032 times)",
            path.display(),
            bomb.len() - 4
        )
    );
    // refused from the header: no time to inflate a gigabyte
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "{:?}",
        start.elapsed()
    );
    // counts beyond the size limit whatever the file's length (normals, uv, doubles)
    let bomb = serialized_bomb(0x2000 | 0x1 | 0x2, u64::from(u32::MAX), u64::from(u32::MAX));
    dir.write("bomb.serialized", &bomb);
    let line = render_refused(&dir, &xml, Duration::from_secs(10), &[]);
    assert!(
        line.ends_with(
            "cannot load mesh: shape 0: 4294967295 vertices and 4294967295 triangles need \
             326417514420 bytes of mesh data, more than the shape_bytes limit of 8 GiB (raise \
             it with PENUMBRA_LIMITS=shape_bytes=...)"
        ),
        "{line}"
    );
}

// ---------------------------------------------------------------------------------------
// 5. radiosity: patch_count x rays_per_patch is bounded when the scene is read
// ---------------------------------------------------------------------------------------

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

#[test]
fn radiosity_form_factor_rays_are_bounded_when_the_scene_is_read() {
    let ladder = repo("scenes/ladder/5-radiosity.xml");
    let defines = |patches: &str, rays: &str| {
        vec![
            ("patch_count".to_string(), patches.to_string()),
            ("rays_per_patch".to_string(), rays.to_string()),
        ]
    };
    // 2 sides x 2^17 patches x 2^10 rays = 2^28, the limit: the description is accepted
    penumbra::scene::Scene::load_description(&ladder, &defines("131072", "1024"))
        .expect("at the limit");
    // one patch more: refused while the scene is read (no mesh loaded, no patch made),
    // at the integrator, naming both parameters
    let e = penumbra::scene::Scene::load_description(&ladder, &defines("131073", "1024"))
        .expect_err("above the limit")
        .to_string();
    assert!(
        e.ends_with(
            "patch_count (131073) x 2 sides x rays_per_patch (1024) of <integrator \
             type=\"radiosity\"> is 268437504 form-factor rays, more than the radiosity_rays \
             limit of 268435456 rays (lower patch_count or rays_per_patch, or raise it with \
             PENUMBRA_LIMITS=radiosity_rays=...)"
        ),
        "{e}"
    );
    assert!(e.contains("5-radiosity.xml:14:"), "{e}");
    // the same through the CLI, at the largest values each parameter takes on its own
    let dir = TempDir::new("radiosity");
    let exr = dir.path("out.exr");
    let args: Vec<&std::ffi::OsStr> = vec![
        "render".as_ref(),
        ladder.as_os_str(),
        "-D".as_ref(),
        "patch_count=4194304".as_ref(),
        "-D".as_ref(),
        "rays_per_patch=1048576".as_ref(),
        "-o".as_ref(),
        exr.as_os_str(),
    ];
    let (code, stderr) = penumbra_within(&dir, &args, Duration::from_secs(10));
    one_error_line(
        code,
        &stderr,
        &[
            "patch_count (4194304) x 2 sides x rays_per_patch (1048576)",
            "8796093022208 form-factor rays",
        ],
    );
}

#[test]
fn radiosity_with_a_patch_size_is_bounded_once_the_patches_are_made() {
    // patch_size 0.01 on a 2 x 2 rectangle: 2 x 283^2 patches, x 2 sides x 2^20 rays
    let dir = TempDir::new("radiosity-size");
    let xml = dir.write(
        "scene.xml",
        r#"<scene version="3.0.0">
    <integrator type="radiosity">
        <float name="patch_size" value="0.01"/>
        <integer name="rays_per_patch" value="1048576"/>
    </integrator>
    <sensor type="perspective">
        <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film>
    </sensor>
    <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
</scene>
"#,
    );
    let line = render_refused(&dir, &xml, Duration::from_secs(10), &[]);
    assert_eq!(
        line,
        "error: radiosity: 160178 patches x 2 sides x 1048576 rays_per_patch is 335917613056 \
         form-factor rays, more than the radiosity_rays limit of 268435456 rays (increase \
         patch_size or lower rays_per_patch, or raise it with \
         PENUMBRA_LIMITS=radiosity_rays=...)"
    );
}
