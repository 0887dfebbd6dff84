//! Long renders: a render killed mid-run and resumed from its checkpoint is bit-identical to
//! an uninterrupted one; checkpoints are never half-written and refuse other scenes or seeds;
//! time limits and error targets stop the render when they should.

mod common;
use common::*;
use penumbra::io::exr;
use penumbra::progressive::{
    relative_standard_error, render_progressive, scene_hash, Checkpoint, ErrorTarget,
    ProgressiveSettings, StopReason,
};
use std::path::PathBuf;
use std::process::Command;
use std::sync::Mutex;
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-prog-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

const SCENE_ARGS: [&str; 4] = ["-D", "res=16", "--seed", "11"];

#[test]
fn killed_and_resumed_render_is_bit_identical_to_an_uninterrupted_one() {
    let dir = tmpdir("resume");
    let scene = repo_path("scenes/cornell-box.xml");
    let spp = "8192"; // 16x16 pixels: 8 passes of 1024 spp
                      // Uninterrupted reference.
    let whole = dir.join("whole.exr");
    let st = bin()
        .arg("render")
        .arg(&scene)
        .args(SCENE_ARGS)
        .args(["--spp", spp, "--quiet", "-o"])
        .arg(&whole)
        .status()
        .unwrap();
    assert!(st.success());
    // Interrupted: checkpoint after every pass, kill -9 once a few passes are on disk.
    let out = dir.join("part.exr");
    let ckpt = dir.join("part.ckpt");
    let mut child = bin()
        .arg("render")
        .arg(&scene)
        .args(SCENE_ARGS)
        .args([
            "--spp",
            spp,
            "--quiet",
            "--checkpoint-every",
            "0s",
            "--checkpoint",
        ])
        .arg(&ckpt)
        .arg("-o")
        .arg(&out)
        .spawn()
        .unwrap();
    let start = Instant::now();
    let mut killed_at = None;
    while start.elapsed() < Duration::from_secs(120) {
        if let Ok(c) = Checkpoint::read(&ckpt) {
            if c.samples >= 2 * 1024 {
                child.kill().unwrap();
                killed_at = Some(c.samples);
                break;
            }
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.wait().unwrap();
    let killed_at = killed_at.expect("the render finished before it could be interrupted");
    assert!(!out.exists(), "no output from the killed run");
    // The checkpoint left behind is complete (checksum verified) and mid-way.
    let c = Checkpoint::read(&ckpt).expect("checkpoint intact after kill");
    assert!(
        c.samples >= killed_at && c.samples < 8192,
        "{} samples",
        c.samples
    );
    let st = bin()
        .arg("render")
        .arg(&scene)
        .args(SCENE_ARGS)
        .args(["--spp", spp, "--quiet", "--resume", "--checkpoint"])
        .arg(&ckpt)
        .arg("-o")
        .arg(&out)
        .status()
        .unwrap();
    assert!(st.success());
    let a = exr::read(&whole).unwrap();
    let b = exr::read(&out).unwrap();
    let bits = |img: &exr::RgbImage| {
        img.rgb
            .iter()
            .flat_map(|p| p.map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        bits(&a),
        bits(&b),
        "resumed render differs from the uninterrupted one"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn resume_refuses_another_scene_or_seed_and_corrupt_checkpoints() {
    let dir = tmpdir("refuse");
    let scene = repo_path("scenes/cornell-box.xml");
    let ckpt = dir.join("c.ckpt");
    let out = dir.join("o.exr");
    let run = |extra: &[&str]| {
        bin()
            .arg("render")
            .arg(&scene)
            .args(["-D", "res=8", "--spp", "4", "--quiet", "--checkpoint"])
            .arg(&ckpt)
            .arg("-o")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    assert!(run(&["--seed", "1"]).status.success());
    for (extra, why) in [
        (vec!["--seed", "2", "--resume"], "seed"),
        (
            vec!["--seed", "1", "-D", "max_depth=3", "--resume"],
            "another scene",
        ),
    ] {
        let o = run(&extra);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.starts_with("error: cannot resume") && err.contains(why),
            "{err}"
        );
    }
    // A truncated or bit-flipped checkpoint is refused with a clear error.
    let bytes = std::fs::read(&ckpt).unwrap();
    std::fs::write(&ckpt, &bytes[..bytes.len() / 2]).unwrap();
    let o = run(&["--seed", "1", "--resume"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a valid penumbra checkpoint"));
    let mut flipped = bytes.clone();
    flipped[100] ^= 1;
    std::fs::write(&ckpt, &flipped).unwrap();
    let o = run(&["--seed", "1", "--resume"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("checksum"));
    std::fs::remove_dir_all(&dir).ok();
}

fn settings(spp: u32) -> ProgressiveSettings {
    ProgressiveSettings {
        spp,
        seed: 3,
        threads: None,
        time_limit: None,
        target_rel_error: None,
        checkpoint: None,
        scene_hash: 0,
        stop: None,
    }
}

#[test]
fn target_error_stops_at_the_first_pass_that_meets_it() {
    let scene = load("scenes/cornell-box.xml", &[("res", "32")]);
    for kind in [ErrorTarget::ImageMean, ErrorTarget::PerPixel] {
        let target = if kind == ErrorTarget::ImageMean {
            2e-3
        } else {
            0.2
        };
        let errors = Mutex::new(Vec::new());
        let s = ProgressiveSettings {
            target_rel_error: Some((target, kind)),
            ..settings(1 << 20)
        };
        let (p, reason) = render_progressive(&scene, &s, None, &|p| {
            errors
                .lock()
                .unwrap()
                .push((p.samples, relative_standard_error(&p.film, kind)))
        })
        .unwrap();
        assert_eq!(reason, StopReason::TargetError);
        let errors = errors.into_inner().unwrap();
        let (last_spp, last) = *errors.last().unwrap();
        assert_eq!(last_spp, p.samples);
        assert!(last <= target, "{kind:?}: stopped at {last} > {target}");
        // every earlier pass with enough samples was still above the target
        for (spp, e) in &errors[..errors.len() - 1] {
            assert!(
                *spp < 16 || *e > target,
                "{kind:?}: {e} at {spp} spp already met the target"
            );
        }
        assert!(p.samples < 1 << 20);
    }
}

#[test]
fn time_limit_stops_the_render() {
    let scene = load("scenes/cornell-box.xml", &[("res", "32")]);
    let s = ProgressiveSettings {
        time_limit: Some(Duration::from_millis(300)),
        ..settings(1 << 24)
    };
    let start = Instant::now();
    let (p, reason) = render_progressive(&scene, &s, None, &|_| {}).unwrap();
    assert_eq!(reason, StopReason::TimeLimit);
    assert!(p.samples > 0 && p.samples < 1 << 24);
    // one pass is 2^18 paths: well under 10 s even on a loaded 2-core machine
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "{:?}",
        start.elapsed()
    );
}

#[test]
fn stop_flag_ends_the_render_after_the_pass_under_way() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let scene = load("scenes/cornell-box.xml", &[("res", "32")]);
    let pass = penumbra::progressive::pass_spp(32, 32) as u64;
    // Set before the render: no pass is rendered.
    let stop = Arc::new(AtomicBool::new(true));
    let s = ProgressiveSettings {
        stop: Some(stop.clone()),
        ..settings(8 * pass as u32)
    };
    let (p, reason) = render_progressive(&scene, &s, None, &|_| {}).unwrap();
    assert_eq!((reason, p.samples), (StopReason::Interrupted, 0));
    // Set (from the callback, as another thread would) during the third pass: the render
    // keeps exactly three passes, whose sums equal an uninterrupted render of that many
    // samples.
    stop.store(false, Ordering::Relaxed);
    let (p, reason) = render_progressive(&scene, &s, None, &|p| {
        if p.samples == 3 * pass {
            stop.store(true, Ordering::Relaxed);
        }
    })
    .unwrap();
    assert_eq!((reason, p.samples), (StopReason::Interrupted, 3 * pass));
    let (whole, reason) =
        render_progressive(&scene, &settings(3 * pass as u32), None, &|_| {}).unwrap();
    assert_eq!(reason, StopReason::SppReached);
    assert_eq!(p.film.image(), whole.film.image());
}

/// A checkpoint or part names its scene by a hash of the description and of every file the
/// scene reads: a texture of a BSDF (also one nested in `twosided`), of an emitter, and a
/// mesh all count, so a render resumed after one of them changed is refused rather than
/// mixed with the old sums.
#[test]
fn the_scene_hash_covers_every_file_the_scene_reads() {
    let dir = tmpdir("hash-files");
    let files = ["albedo.exr", "back.exr", "radiance.exr", "mesh.obj"];
    for f in files {
        std::fs::write(dir.join(f), format!("{f} v1")).unwrap();
    }
    let xml = dir.join("scene.xml");
    std::fs::write(
        &xml,
        r#"<scene version="3.0.0">
    <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
    <shape type="obj"><string name="filename" value="mesh.obj"/>
        <bsdf type="twosided">
            <bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="albedo.exr"/></texture></bsdf>
            <bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="back.exr"/></texture></bsdf>
        </bsdf>
    </shape>
    <shape type="sphere">
        <emitter type="area"><texture type="bitmap" name="radiance"><string name="filename" value="radiance.exr"/></texture></emitter>
    </shape>
</scene>"#,
    )
    .unwrap();
    let desc = || penumbra::scene::Scene::load_description(&xml, &[]).expect("scene loads");
    let mut listed: Vec<String> = desc()
        .files()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    listed.sort();
    let mut expected: Vec<String> = files.iter().map(|f| f.to_string()).collect();
    expected.sort();
    assert_eq!(listed, expected);
    let before = scene_hash(&desc());
    for f in files {
        std::fs::write(dir.join(f), format!("{f} v2")).unwrap();
        let after = scene_hash(&desc());
        assert_ne!(before, after, "{f} changed, the hash did not");
        std::fs::write(dir.join(f), format!("{f} v1")).unwrap();
        assert_eq!(scene_hash(&desc()), before, "{f} restored");
    }
    std::fs::remove_dir_all(&dir).ok();
}
