//! A render that cannot be lost (issue 40): outputs are checked for writability before any
//! rendering; SIGINT and SIGTERM stop the render at the end of a pass with its image and
//! checkpoint written and a distinct exit status, and the checkpoint resumes bit-identically;
//! outputs are written atomically (writers racing for one path never mix or truncate it);
//! a failed checkpoint write never ends the render; `--strict` fails on non-finite samples.

mod common;
use common::*;
use penumbra::io::exr::{self, Attribute, RgbImage};
use penumbra::progressive::Checkpoint;
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_penumbra"));
    c.env("RUST_BACKTRACE", "1");
    c
}

/// A temporary directory unique to this process and test, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("penumbra-durable-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The file names in `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// The Cornell box at 16x16 (passes of 256 spp) with a fixed seed.
fn cornell() -> PathBuf {
    repo_path("scenes/cornell-box.xml")
}
const CORNELL_ARGS: [&str; 4] = ["-D", "res=16", "--seed", "7"];

/// A child's stderr, read line by line on a thread.
struct Lines {
    rx: mpsc::Receiver<String>,
    seen: Vec<String>,
}

impl Lines {
    fn of(child: &mut Child) -> Self {
        let err = child.stderr.take().expect("stderr piped");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in std::io::BufReader::new(err).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Lines {
            rx,
            seen: Vec::new(),
        }
    }

    /// Collects the lines that have arrived.
    fn poll(&mut self) -> &[String] {
        while let Ok(l) = self.rx.try_recv() {
            self.seen.push(l);
        }
        &self.seen
    }

    /// Every line, once the child has closed its stderr.
    fn all(mut self) -> Vec<String> {
        while let Ok(l) = self.rx.recv_timeout(Duration::from_secs(10)) {
            self.seen.push(l);
        }
        self.seen
    }
}

/// Waits for `child` at most `limit`; kills it and fails if it runs longer.
fn wait_at_most(child: &mut Child, limit: Duration, what: &str) -> ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return st;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn send(child: &Child, signal: &str) {
    let st = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success(), "kill -{signal} failed");
}

/// Polls until `path` holds a valid checkpoint (checksum verified) with samples, while the
/// child runs.
fn wait_for_checkpoint(child: &mut Child, path: &Path) -> Checkpoint {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(120) {
        if let Ok(c) = Checkpoint::read(path) {
            if c.samples > 0 {
                return c;
            }
        }
        if let Some(st) = child.try_wait().unwrap() {
            panic!("the render ended ({st}) before its first checkpoint");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    panic!("no checkpoint at {} after 120 s", path.display());
}

fn bits(img: &RgbImage) -> Vec<u32> {
    img.rgb.iter().flat_map(|p| p.map(f32::to_bits)).collect()
}

fn read_exr(path: &Path) -> RgbImage {
    exr::read(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

// ---------------------------------------------------------------------------------------
// 1. Unwritable outputs fail before rendering
// ---------------------------------------------------------------------------------------

/// Runs a render of 10^9 spp (hours) with `extra` arguments; it must fail at once with one
/// `error:` line containing `parts`, before rendering anything.
fn fails_at_once(dir: &TempDir, extra: &[&std::ffi::OsStr], parts: &[&str]) {
    let start = Instant::now();
    let mut child = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", "1000000000", "--threads", "1"])
        .args(extra)
        .current_dir(&dir.0)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = Lines::of(&mut child);
    let st = wait_at_most(&mut child, Duration::from_secs(10), "an unwritable output");
    let elapsed = start.elapsed();
    let lines = lines.all();
    assert_eq!(st.code(), Some(1), "{lines:?}");
    assert_eq!(lines.len(), 1, "one line: {lines:?}");
    assert!(lines[0].starts_with("error: "), "{lines:?}");
    for p in parts {
        assert!(lines[0].contains(p), "{p:?} not in {:?}", lines[0]);
    }
    // Before the scene is even loaded: a fraction of a second in a debug build.
    assert!(
        elapsed < Duration::from_millis(800),
        "took {elapsed:?} to fail"
    );
}

#[test]
fn unwritable_outputs_fail_before_rendering() {
    let dir = TempDir::new("unwritable");
    let os = |s: &str| std::ffi::OsString::from(s);
    let cases: Vec<(Vec<std::ffi::OsString>, Vec<&str>)> = vec![
        (
            vec![os("-o"), os("/nonexistent-dir/out.exr")],
            vec![
                "/nonexistent-dir/out.exr: cannot write image",
                "no such directory /nonexistent-dir",
            ],
        ),
        (
            vec![
                os("-o"),
                os("ok.exr"),
                os("--stats"),
                os("/nonexistent-dir/s.json"),
            ],
            vec!["/nonexistent-dir/s.json: cannot write statistics"],
        ),
        (
            vec![
                os("-o"),
                os("ok.exr"),
                os("--preview"),
                os("/nonexistent-dir/p.png"),
            ],
            vec!["/nonexistent-dir/p.png: cannot write preview"],
        ),
        (
            vec![
                os("-o"),
                os("ok.exr"),
                os("--checkpoint-every"),
                os("1m"),
                os("--checkpoint"),
                os("/nonexistent-dir/c.ckpt"),
            ],
            vec!["/nonexistent-dir/c.ckpt: cannot write checkpoint"],
        ),
        (
            vec![
                os("--part"),
                os("0/2"),
                os("-o"),
                os("/nonexistent-dir/p.pnbr"),
            ],
            vec!["/nonexistent-dir/p.pnbr: cannot write part file"],
        ),
        (
            vec![os("-o"), dir.0.clone().into_os_string()],
            vec!["cannot write image: is a directory"],
        ),
    ];
    for (args, parts) in &cases {
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        fails_at_once(&dir, &args, parts);
    }
    // A directory that exists but takes no new file. /sys refuses even root (CI runs as
    // root, for whom a mode-0555 directory is writable); the read-only directory is tried
    // where its mode is enforced.
    #[cfg(target_os = "linux")]
    fails_at_once(
        &dir,
        &["-o".as_ref(), "/sys/out.exr".as_ref()],
        &["/sys/out.exr: cannot write image: cannot create a file in /sys"],
    );
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.path("read-only");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        if std::fs::write(ro.join("probe"), b"").is_err() {
            let out = ro.join("out.exr");
            fails_at_once(
                &dir,
                &["-o".as_ref(), out.as_os_str()],
                &[
                    "cannot write image: cannot create a file in",
                    "ermission denied",
                ],
            );
        }
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    assert_eq!(
        entries(&dir.0),
        ["read-only"],
        "nothing written, no probe file left"
    );
}

// ---------------------------------------------------------------------------------------
// 2. SIGINT / SIGTERM
// ---------------------------------------------------------------------------------------

/// SIGTERM (as Slurm sends at a job's time limit) after the first checkpoint: the render ends
/// at the end of the pass with exit status 143, the image so far and its checkpoint written
/// and one line saying so; a second SIGTERM during the stop changes nothing; `--resume` to
/// the full spp gives an image bit-identical to the uninterrupted render's.
#[test]
fn sigterm_saves_the_render_and_resume_is_bit_identical() {
    let dir = TempDir::new("sigterm");
    let spp = "8192"; // 32 passes of 256 spp
    let whole = dir.path("whole.exr");
    let st = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", spp, "--quiet", "-o"])
        .arg(&whole)
        .status()
        .unwrap();
    assert!(st.success());

    let out = dir.path("out.exr");
    let ckpt = dir.path("out.ckpt");
    let mut child = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", spp, "--quiet", "--checkpoint-every", "0s"])
        .arg("--checkpoint")
        .arg(&ckpt)
        .arg("-o")
        .arg(&out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = Lines::of(&mut child);
    let first = wait_for_checkpoint(&mut child, &ckpt);
    send(&child, "TERM");
    std::thread::sleep(Duration::from_millis(20));
    if child.try_wait().unwrap().is_none() {
        send(&child, "TERM");
    }
    let st = wait_at_most(
        &mut child,
        Duration::from_secs(60),
        "the interrupted render",
    );
    let lines = lines.all();
    assert_eq!(st.code(), Some(143), "{lines:?}");
    let saved = Checkpoint::read(&ckpt).expect("the checkpoint is whole");
    assert!(
        saved.samples >= first.samples && saved.samples < 8192,
        "{} samples",
        saved.samples
    );
    assert_eq!(
        lines,
        [format!(
            "interrupted by SIGTERM after {} of 8192 spp: wrote {} and the checkpoint {} \
             (continue with --resume)",
            saved.samples,
            out.display(),
            ckpt.display()
        )]
    );
    // The image so far holds the checkpoint's samples.
    let partial = read_exr(&out);
    assert_eq!(partial.spp(), Some(saved.samples as f64));
    assert_eq!(
        partial.attributes.get("stop_reason").map(String::as_str),
        Some("interrupted")
    );
    assert_eq!(entries(&dir.0), ["out.ckpt", "out.exr", "whole.exr"]);

    let st = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", spp, "--quiet", "--resume", "--checkpoint"])
        .arg(&ckpt)
        .arg("-o")
        .arg(&out)
        .status()
        .unwrap();
    assert!(st.success());
    assert_eq!(read_exr(&out).spp(), Some(8192.0));
    assert!(
        bits(&read_exr(&out)) == bits(&read_exr(&whole)),
        "the resumed render differs from the uninterrupted one"
    );
}

/// SIGINT (Ctrl-C) without checkpointing: the image so far, status 130.
#[test]
fn sigint_writes_the_image_so_far_with_status_130() {
    let dir = TempDir::new("sigint");
    let out = dir.path("out.exr");
    let mut child = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", "1000000", "--quiet", "-o"])
        .arg(&out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = Lines::of(&mut child);
    // Long enough for a pass or two (an interruption before the first pass writes nothing,
    // and says so).
    std::thread::sleep(Duration::from_millis(1500));
    send(&child, "INT");
    let st = wait_at_most(
        &mut child,
        Duration::from_secs(60),
        "the interrupted render",
    );
    let lines = lines.all();
    assert_eq!(st.code(), Some(130), "{lines:?}");
    let img = read_exr(&out);
    let spp = img.spp().expect("spp attribute");
    assert!(spp > 0.0 && spp < 1e6, "{spp}");
    assert_eq!(
        lines,
        [format!(
            "interrupted by SIGINT after {spp} of 1000000 spp: wrote {}",
            out.display()
        )]
    );
    assert_eq!(
        entries(&dir.0),
        ["out.exr"],
        "no checkpoint unless asked for"
    );
}

/// A part interrupted by SIGTERM writes its samples so far to its checkpoint (not to the
/// part file, which `merge` would take for a whole part), and `--resume` completes it: the
/// merge of the resumed part with the other is the one-process render, bit for bit.
#[test]
fn an_interrupted_part_resumes_from_its_checkpoint() {
    let dir = TempDir::new("part");
    let spp = "8192";
    let render = |extra: &[&std::ffi::OsStr]| {
        let mut c = bin();
        c.arg("render")
            .arg(cornell())
            .args(CORNELL_ARGS)
            .args(["--spp", spp, "--quiet"])
            .args(extra);
        c
    };
    let whole = dir.path("whole.exr");
    assert!(render(&["-o".as_ref(), whole.as_os_str()])
        .status()
        .unwrap()
        .success());
    let p0 = dir.path("p0.pnbr");
    let p1 = dir.path("p1.pnbr");
    let ckpt = dir.path("p1.pnbr.ckpt");
    assert!(render(&[
        "--part".as_ref(),
        "0/2".as_ref(),
        "-o".as_ref(),
        p0.as_os_str()
    ])
    .status()
    .unwrap()
    .success());
    let mut child = render(&[
        "--part".as_ref(),
        "1/2".as_ref(),
        "--checkpoint-every".as_ref(),
        "0s".as_ref(),
        "-o".as_ref(),
        p1.as_os_str(),
    ])
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let lines = Lines::of(&mut child);
    wait_for_checkpoint(&mut child, &ckpt);
    send(&child, "TERM");
    let st = wait_at_most(&mut child, Duration::from_secs(60), "the interrupted part");
    let lines = lines.all();
    assert_eq!(st.code(), Some(143), "{lines:?}");
    let saved = Checkpoint::read(&ckpt).expect("the part's checkpoint is whole");
    assert_eq!(saved.part, Some((1, 2)));
    assert!(
        saved.samples > 0 && saved.samples < 4096,
        "{}",
        saved.samples
    );
    assert_eq!(
        lines,
        [format!(
            "interrupted by SIGTERM: part 1/2 stopped after samples 4096..{}; its checkpoint \
             {} holds them (continue with --resume); no part file written",
            4096 + saved.samples,
            ckpt.display()
        )]
    );
    assert!(!p1.exists());
    let st = render(&[
        "--part".as_ref(),
        "1/2".as_ref(),
        "--resume".as_ref(),
        "-o".as_ref(),
        p1.as_os_str(),
    ])
    .status()
    .unwrap();
    assert!(st.success());
    assert!(!ckpt.exists(), "the completed part's checkpoint is removed");
    let merged = dir.path("merged.exr");
    let st = bin()
        .args(["merge", "--quiet", "-o"])
        .arg(&merged)
        .arg(&p0)
        .arg(&p1)
        .status()
        .unwrap();
    assert!(st.success());
    assert!(
        bits(&read_exr(&merged)) == bits(&read_exr(&whole)),
        "the merge of the resumed part differs from the one-process render"
    );
}

// ---------------------------------------------------------------------------------------
// 3. Atomic outputs
// ---------------------------------------------------------------------------------------

fn image(width: usize, height: usize, v: f32) -> RgbImage {
    RgbImage {
        width,
        height,
        rgb: (0..width * height).map(|i| [v, v + i as f32, -v]).collect(),
        variance: None,
        attributes: Default::default(),
    }
}

/// Two writers write their own image to one path, over and over, while a reader reads it:
/// every read is a whole EXR equal to one of the two images (never a mixture of the two, a
/// truncated file or a missing one), and no temporary file is left. With a fixed temporary
/// name the writers renamed each other's half-written files (and failed on the missing
/// ones).
#[test]
fn writers_racing_for_one_exr_never_mix_or_truncate_it() {
    let dir = TempDir::new("race-exr");
    let path = dir.path("out.exr");
    let (a, b) = (image(256, 128, 1.0), image(256, 128, 2.0));
    exr::write(&path, &a, &[]).unwrap();
    let done = std::sync::atomic::AtomicBool::new(false);
    let reads = std::thread::scope(|s| {
        let writers: Vec<_> = [&a, &b]
            .into_iter()
            .map(|img| {
                let path = &path;
                s.spawn(move || {
                    for i in 0..60 {
                        exr::write(path, img, &[("i", Attribute::Int(i))])
                            .unwrap_or_else(|e| panic!("write {i}: {e}"));
                    }
                })
            })
            .collect();
        let reader = s.spawn(|| {
            let mut reads = 0;
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                let got = exr::read(&path).unwrap_or_else(|e| panic!("read {reads}: {e}"));
                assert!(
                    got.rgb == a.rgb || got.rgb == b.rgb,
                    "read {reads}: neither writer's image"
                );
                reads += 1;
            }
            reads
        });
        // Every writer is joined and the reader stopped before any failure is reported, so
        // that a failing writer fails the test rather than leaving the reader spinning.
        let results: Vec<_> = writers.into_iter().map(|w| w.join()).collect();
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        let reads = reader.join();
        for r in results {
            r.expect("a writer failed");
        }
        reads.expect("the reader failed")
    });
    assert!(reads > 0);
    let last = read_exr(&path);
    assert!(last.rgb == a.rgb || last.rgb == b.rgb);
    assert_eq!(entries(&dir.0), ["out.exr"], "temporary files left behind");
}

/// The same for checkpoints (and so part files) and PNG previews, written by two processes'
/// worth of threads each.
#[test]
fn writers_racing_for_one_checkpoint_or_preview_never_mix_them() {
    let dir = TempDir::new("race-ckpt");
    let scene = scene_from_str(
        r#"<scene version="3.0.0">
    <sensor type="perspective">
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/></film>
        <sampler type="independent"/>
    </sensor>
    <emitter type="constant"/>
</scene>"#,
    );
    let plan = |index| penumbra::progressive::PartPlan {
        index,
        count: 2,
        plan_spp: 128, // two passes of 64 spp
        start_spp: 0,
    };
    let parts: Vec<Checkpoint> = (0..2)
        .map(|i| penumbra::progressive::render_part(&scene, &plan(i), 1, Some(1), 9).unwrap())
        .collect();
    let bytes: Vec<Vec<u8>> = parts.iter().map(Checkpoint::to_bytes).collect();
    let ckpt = dir.path("out.ckpt");
    parts[0].write(&ckpt).unwrap();
    let png = dir.path("out.png");
    let pixels: Vec<Vec<[f32; 3]>> = [0.2f32, 0.7]
        .iter()
        .map(|&v| {
            (0..256 * 256)
                .map(|i| [v, (i % 256) as f32 / 255.0, 0.5])
                .collect()
        })
        .collect();
    penumbra::io::png::write_preview(&png, 256, 256, &pixels[0], 1.0).unwrap();
    let pngs: Vec<Vec<u8>> = (0..2)
        .map(|k| {
            let p = dir.path(&format!("ref{k}.png"));
            penumbra::io::png::write_preview(&p, 256, 256, &pixels[k], 1.0).unwrap();
            let b = std::fs::read(&p).unwrap();
            std::fs::remove_file(&p).unwrap();
            b
        })
        .collect();
    let done = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|s| {
        let mut writers = Vec::new();
        for k in 0..2 {
            let (parts, ckpt, png, pixels) = (&parts, &ckpt, &png, &pixels);
            writers.push(s.spawn(move || {
                for i in 0..40 {
                    parts[k]
                        .write(ckpt)
                        .unwrap_or_else(|e| panic!("checkpoint write {i}: {e}"));
                    penumbra::io::png::write_preview(png, 256, 256, &pixels[k], 1.0)
                        .unwrap_or_else(|e| panic!("preview write {i}: {e}"));
                }
            }));
        }
        let reader = s.spawn(|| {
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                let c = std::fs::read(&ckpt).expect("the checkpoint is there");
                assert!(bytes.contains(&c), "a checkpoint of neither writer");
                Checkpoint::parse(&c, &ckpt).expect("a valid checkpoint");
                let p = std::fs::read(&png).expect("the preview is there");
                assert!(pngs.contains(&p), "a preview of neither writer");
            }
        });
        let results: Vec<_> = writers.into_iter().map(|w| w.join()).collect();
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        let read = reader.join();
        for r in results {
            r.expect("a writer failed");
        }
        read.expect("the reader failed");
    });
    assert_eq!(
        entries(&dir.0),
        ["out.ckpt", "out.png"],
        "temporary files left"
    );
}

// ---------------------------------------------------------------------------------------
// 4. A failed checkpoint write is not fatal
// ---------------------------------------------------------------------------------------

/// The checkpoint's directory disappears after the first checkpoint (root can write into a
/// read-only directory, so it is removed instead): every later checkpoint fails, which one
/// warning line reports, and the render goes on to its full spp and writes its image. Once
/// the directory is back, the next checkpoint succeeds; here it comes back only after the
/// render, so the final checkpoint's failure is the error the run ends with, after the image.
#[test]
fn a_failed_checkpoint_write_warns_and_the_render_goes_on() {
    let dir = TempDir::new("ckpt-fails");
    let ck_dir = dir.path("ck");
    std::fs::create_dir(&ck_dir).unwrap();
    let ckpt = ck_dir.join("r.ckpt");
    let out = dir.path("out.exr");
    let mut child = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", "4096", "--quiet", "--checkpoint-every", "0s"])
        .arg("--checkpoint")
        .arg(&ckpt)
        .arg("-o")
        .arg(&out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = Lines::of(&mut child);
    wait_for_checkpoint(&mut child, &ckpt);
    std::fs::remove_dir_all(&ck_dir).unwrap();
    let st = wait_at_most(&mut child, Duration::from_secs(300), "the render");
    let lines = lines.all();
    assert_eq!(st.code(), Some(1), "{lines:?}");
    assert_eq!(lines.len(), 2, "one warning, one error: {lines:?}");
    assert!(
        lines[0].starts_with("warning: checkpoint not written, the render goes on")
            && lines[0].contains(&format!(
                "{}: no such directory {}",
                ckpt.display(),
                ck_dir.display()
            ))
            && lines[0].ends_with("(3 attempts)"),
        "{lines:?}"
    );
    assert!(
        lines[1].starts_with("error: the final checkpoint was not written: ")
            && lines[1].ends_with(&format!("(the image was written to {})", out.display())),
        "{lines:?}"
    );
    assert_eq!(read_exr(&out).spp(), Some(4096.0), "the whole render");
}

/// As above, but the directory comes back while the render runs: the render succeeds and its
/// final checkpoint holds every sample.
#[test]
fn checkpoints_resume_once_the_directory_is_back() {
    let dir = TempDir::new("ckpt-back");
    let ck_dir = dir.path("ck");
    std::fs::create_dir(&ck_dir).unwrap();
    let ckpt = ck_dir.join("r.ckpt");
    let out = dir.path("out.exr");
    let mut child = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", "8192", "--quiet", "--checkpoint-every", "0s"])
        .arg("--checkpoint")
        .arg(&ckpt)
        .arg("-o")
        .arg(&out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = Lines::of(&mut child);
    wait_for_checkpoint(&mut child, &ckpt);
    std::fs::remove_dir_all(&ck_dir).unwrap();
    let start = Instant::now();
    while lines.poll().is_empty() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the render ended before its checkpoint failed"
        );
        assert!(start.elapsed() < Duration::from_secs(120), "no warning");
        std::thread::sleep(Duration::from_millis(5));
    }
    std::fs::create_dir(&ck_dir).unwrap();
    let st = wait_at_most(&mut child, Duration::from_secs(300), "the render");
    let lines = lines.all();
    assert_eq!(st.code(), Some(0), "{lines:?}");
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].starts_with("warning: checkpoint not written"));
    assert_eq!(Checkpoint::read(&ckpt).unwrap().samples, 8192);
    assert_eq!(read_exr(&out).spp(), Some(8192.0));
}

// ---------------------------------------------------------------------------------------
// 5. --strict
// ---------------------------------------------------------------------------------------

/// A scene of finite numbers whose samples overflow: a point light and an environment of
/// 3e38 (about f32::MAX) each, whose contributions add up to infinity.
const OVERFLOWING: &str = r#"<scene version="3.0.0">
    <integrator type="path"/>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/><rfilter type="box"/></film>
        <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="3e38"/></emitter>
    <emitter type="point"><point name="position" x="0" y="0" z="2"/><rgb name="intensity" value="3e38"/></emitter>
    <shape type="sphere"><bsdf type="diffuse"/></shape>
</scene>
"#;

#[test]
fn strict_fails_on_non_finite_samples_after_writing_the_image() {
    let dir = TempDir::new("strict");
    let scene = dir.path("overflow.xml");
    std::fs::write(&scene, OVERFLOWING).unwrap();
    let out = dir.path("out.exr");
    let run = |strict: bool| {
        let mut c = bin();
        c.arg("render")
            .arg(&scene)
            .args(["--quiet", "-o"])
            .arg(&out);
        if strict {
            c.arg("--strict");
        }
        c.output().unwrap()
    };
    // Without --strict: dropped and counted, status 0.
    let plain = run(false);
    assert!(plain.status.success());
    let n: f64 = read_exr(&out).attributes["nonfinite_samples"]
        .parse()
        .unwrap();
    assert!(n > 0.0, "the scene must produce non-finite samples");
    std::fs::remove_file(&out).unwrap();
    // With --strict: the image is written, then one error line naming the count.
    let strict = run(true);
    let err = String::from_utf8_lossy(&strict.stderr);
    assert_eq!(strict.status.code(), Some(1), "{err}");
    assert_eq!(
        err,
        format!(
            "error: {n} non-finite samples were dropped (--strict); the image was written to {}\n",
            out.display()
        )
    );
    assert_eq!(read_exr(&out).spp(), Some(16.0));
    // A render without them passes --strict.
    let clean = bin()
        .arg("render")
        .arg(cornell())
        .args(CORNELL_ARGS)
        .args(["--spp", "16", "--quiet", "--strict", "-o"])
        .arg(dir.path("clean.exr"))
        .output()
        .unwrap();
    assert!(
        clean.status.success(),
        "{}",
        String::from_utf8_lossy(&clean.stderr)
    );
}
