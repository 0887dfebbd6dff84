//! Split renders: `render --part i/N` renders whole passes of a render's samples, `merge`
//! adds the parts' exact sums. The merge of any split, in any order, must be bit-identical to
//! the render made in one process (same seed and spp), extending a render by more parts must
//! equal rendering the larger spp at once, and bad sets of parts must be refused with one
//! line naming what is wrong.

mod common;

use common::*;
use penumbra::film::Film;
use penumbra::progressive::{
    merge_parts, pass_spp, render_part, render_part_with, render_progressive, scene_hash,
    Checkpoint, Checkpointing, PartPlan, PartSettings, ProgressiveSettings,
};
use penumbra::render::Job;
use penumbra::scene::Scene;
use std::path::PathBuf;

const SEED: u64 = 1234;

fn load_with_hash(rel: &str, defines: &[(&str, &str)]) -> (Job, u64) {
    let defines: Vec<(String, String)> = defines
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let desc = Scene::load_description(&repo_path(rel), &defines).expect("loads");
    let hash = scene_hash(&desc);
    (Job::build(&desc).expect("builds"), hash)
}

fn one_process(scene: &Job, hash: u64, spp: u32) -> Film {
    let settings = ProgressiveSettings {
        spp,
        seed: SEED,
        threads: None,
        time_limit: None,
        target_rel_error: None,
        checkpoint: None,
        scene_hash: hash,
        stop: None,
    };
    render_progressive(scene, &settings, None, &|_| {})
        .expect("renders")
        .0
        .film
}

fn part(scene: &Job, hash: u64, i: u32, n: u32, spp: u64, start: u64) -> (PathBuf, Checkpoint) {
    let plan = PartPlan {
        index: i,
        count: n,
        plan_spp: spp,
        start_spp: start,
    };
    let c = render_part(scene, &plan, SEED, None, hash).expect("part renders");
    (PathBuf::from(format!("part-{start}-{spp}-{i}-of-{n}")), c)
}

/// Every sum of the two films, bit for bit.
fn assert_bit_identical(a: &Film, b: &Film, what: &str) {
    let bits = |f: &Film| {
        let mut v: Vec<u64> = Vec::new();
        for i in 0..f.sum.len() {
            for c in 0..3 {
                v.push(f.sum[i][c].to_bits());
                v.push(f.sum_sq[i][c].to_bits());
                v.push(f.sum_w2[i][c].to_bits());
                v.push(f.sum_sq_w2[i][c].to_bits());
            }
            v.push(f.weight[i].to_bits());
            v.push(f.weight_sq[i].to_bits());
            v.push(f.weight_cube[i].to_bits());
        }
        v
    };
    assert_eq!(a.samples, b.samples, "{what}: sample counts");
    assert!(bits(a) == bits(b), "{what}: the sums differ");
    let img = |f: &Film| -> Vec<u32> {
        f.image()
            .iter()
            .chain(f.sample_variance().iter())
            .flat_map(|p| p.map(f32::to_bits))
            .collect()
    };
    assert!(img(a) == img(b), "{what}: the images differ");
}

#[test]
fn any_split_in_any_order_merges_to_the_one_process_render() {
    // 64 × 64 px: passes of 64 spp, so 300 spp are 5 passes (4 × 64 + 44).
    let (scene, hash) = load_with_hash("scenes/cornell-box.xml", &[("res", "64")]);
    assert_eq!(pass_spp(scene.scene.width, scene.scene.height), 64);
    let single = one_process(&scene, hash, 300);
    for n in [1u32, 2, 3, 5] {
        let mut parts: Vec<_> = (0..n).map(|i| part(&scene, hash, i, n, 300, 0)).collect();
        // Merge in a scrambled order.
        parts.reverse();
        if parts.len() > 2 {
            parts.swap(0, 1);
        }
        let merged = merge_parts(parts, None).expect("merges");
        assert_eq!(merged.samples, 300);
        assert_bit_identical(&merged.film(), &single, &format!("{n} parts"));
    }
    // A wide filter splats across pixels and tiles: the same holds.
    let (scene, hash) = load_with_hash("scenes/cornell-gaussian.xml", &[("res", "32")]);
    let single = one_process(&scene, hash, 600);
    let parts = (0..3).map(|i| part(&scene, hash, i, 3, 600, 0)).collect();
    assert_bit_identical(
        &merge_parts(parts, None).expect("merges").film(),
        &single,
        "gaussian filter, 3 parts",
    );
}

#[test]
fn more_parts_extend_a_render_as_rendering_more_spp_does() {
    let (scene, hash) = load_with_hash("scenes/cornell-box.xml", &[("res", "64")]);
    let first: Vec<_> = (0..2).map(|i| part(&scene, hash, i, 2, 192, 0)).collect();
    let more: Vec<_> = (0..2).map(|i| part(&scene, hash, i, 2, 300, 192)).collect();
    let all: Vec<_> = first.iter().cloned().chain(more).collect();
    assert_bit_identical(
        &merge_parts(all.clone(), None).expect("merges").film(),
        &one_process(&scene, hash, 300),
        "192 spp extended to 300",
    );
    // A ladder rung: the samples up to a part boundary, as a 192-spp render.
    assert_bit_identical(
        &merge_parts(all, Some(192)).expect("merges").film(),
        &one_process(&scene, hash, 192),
        "the first 192 spp",
    );
}

#[test]
fn bad_sets_of_parts_are_refused_with_one_line() {
    let (scene, hash) = load_with_hash("scenes/cornell-box.xml", &[("res", "64")]);
    let p = |i, n| part(&scene, hash, i, n, 300, 0);
    let (a0, a1, a2) = (p(0, 3), p(1, 3), p(2, 3));
    let (other_scene, other_hash) = load_with_hash(
        "scenes/cornell-box.xml",
        &[("res", "64"), ("max_depth", "3")],
    );
    let foreign = part(&other_scene, other_hash, 1, 3, 300, 0);
    let mut other_seed = a1.clone();
    other_seed.1.seed += 1;
    let mut other_version = a1.clone();
    other_version.1.version = "0.0.0-other".into();
    let mut checkpoint = a1.clone();
    checkpoint.1.part = None;
    let overlapping = p(0, 2); // samples 0..128, over a0 (0..64) and a1 (64..192)
    let cases: Vec<(Vec<(PathBuf, Checkpoint)>, &str)> = vec![
        (
            vec![a0.clone(), a2.clone()],
            "parts 1/3 of 300 spp (samples 64..192) are not among",
        ),
        (
            vec![a1.clone(), a2.clone()],
            "parts 0/3 of 300 spp (samples 0..64) are not among",
        ),
        (
            vec![a0.clone(), a1.clone()],
            "parts 2/3 of 300 spp (samples 192..300) are not among",
        ),
        (
            vec![a0.clone(), a1.clone(), a1.clone(), a2.clone()],
            "duplicate parts",
        ),
        (
            vec![a0.clone(), overlapping, a1.clone(), a2.clone()],
            "overlapping parts",
        ),
        (vec![a0.clone(), foreign, a2.clone()], "from another scene"),
        (
            vec![a0.clone(), other_seed, a2.clone()],
            "with another seed",
        ),
        (
            vec![a0.clone(), other_version, a2.clone()],
            "by another penumbra version",
        ),
        (
            vec![a0.clone(), checkpoint, a2.clone()],
            "is a checkpoint, not a part file",
        ),
        (vec![a0.clone(), a1.clone(), a2.clone()], ""),
        (vec![], "no part files"),
    ];
    for (parts, expected) in cases {
        let names: Vec<String> = parts.iter().map(|(n, _)| n.display().to_string()).collect();
        match merge_parts(parts, None) {
            Ok(_) => assert!(
                expected.is_empty(),
                "{names:?}: merged, expected {expected}"
            ),
            Err(e) => {
                let e = e.to_string();
                assert!(
                    !expected.is_empty() && e.contains(expected),
                    "{names:?}: {e} (expected {expected})"
                );
                assert!(!e.contains('\n'), "{e}");
            }
        }
    }
    // A --spp that is not a part boundary.
    let e = merge_parts(vec![a0, a1, a2], Some(100)).expect_err("inside a part");
    assert!(e.to_string().contains("falls inside"), "{e}");
    // Impossible plans.
    for (i, n, start, why) in [
        (0u32, 6u32, 0u64, "at most 5 parts"),
        (0, 2, 100, "multiple of the pass size"),
        (3, 3, 0, "below the part count"),
    ] {
        let plan = PartPlan {
            index: i,
            count: n,
            plan_spp: 300,
            start_spp: start,
        };
        let e = render_part(&scene, &plan, SEED, None, hash).expect_err("refused");
        assert!(e.to_string().contains(why), "{e}");
    }
}

#[test]
fn part_files_round_trip_and_corruption_is_refused() {
    let (scene, hash) = load_with_hash("scenes/cornell-box.xml", &[("res", "16")]);
    let (_, c) = part(&scene, hash, 0, 1, 8, 0);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("parts-roundtrip");
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let path = dir.join("p.pnbr");
    c.write(&path).expect("writes");
    let back = Checkpoint::read(&path).expect("reads");
    assert_eq!(back.exact, c.exact);
    assert_eq!(
        (back.first_sample, back.samples, back.plan_spp, back.part),
        (0, 8, 8, Some((0, 1)))
    );
    assert_eq!(back.filter, c.filter);
    let mut bytes = std::fs::read(&path).expect("bytes");
    let mid = bytes.len() / 2;
    bytes[mid] ^= 1;
    std::fs::write(&path, &bytes).expect("write");
    let e = Checkpoint::read(&path).expect_err("corrupt");
    assert!(e.to_string().contains("checksum mismatch"), "{e}");
}

/// The command line: `render --part` writes a part file, `merge` reads them; bad input ends in
/// one error line.
#[test]
fn command_line_parts_and_merge() {
    let bin = env!("CARGO_BIN_EXE_penumbra");
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("parts-cli");
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let scene = repo_path("scenes/cornell-box.xml");
    let run = |args: &[&str]| {
        std::process::Command::new(bin)
            .args(args)
            .output()
            .expect("runs")
    };
    let err_line = |o: &std::process::Output| {
        let e = String::from_utf8_lossy(&o.stderr).trim().to_string();
        assert!(!o.status.success(), "succeeded: {e}");
        e
    };
    let s = scene.to_str().expect("utf-8");
    // Renders parts 0/2 and 1/2 (their paths from `name`), merges them in reverse order and
    // renders the same samples in one process, with `extra` flags; the two images.
    let split_and_whole = |tag: &str, extra: &[&str]| {
        let name = |i: u32| dir.join(format!("{tag}{i}.pnbr")).display().to_string();
        let base = ["render", s, "-D", "res=16", "--spp", "600", "--quiet"];
        for i in 0..2 {
            let part = format!("{i}/2");
            let out = name(i);
            let mut args = base.to_vec();
            args.extend(extra);
            args.extend(["--part", &part, "-o", &out]);
            let o = run(&args);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
        let merged = dir.join(format!("merged-{tag}.exr")).display().to_string();
        let o = run(&["merge", &name(1), &name(0), "--quiet", "-o", &merged]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let single = dir.join(format!("single-{tag}.exr")).display().to_string();
        let mut args = base.to_vec();
        args.extend(extra);
        args.extend(["-o", &single]);
        assert!(run(&args).status.success());
        (
            penumbra::io::exr::read(std::path::Path::new(&merged)).expect("merged"),
            penumbra::io::exr::read(std::path::Path::new(&single)).expect("single"),
        )
    };
    let p = |i: u32| dir.join(format!("p{i}.pnbr")).display().to_string();
    let (a, rgb_single) = split_and_whole("p", &[]);
    assert!(
        a.rgb == rgb_single.rgb,
        "merged EXR differs from the one-process render"
    );
    // Errors: one line each.
    for (args, expected) in [
        (
            vec!["render", s, "--part", "2/2", "-o", "x.pnbr"],
            "is not a part",
        ),
        (vec!["merge", &p(0), "-o", "x.exr"], "missing samples"),
        (vec!["merge", "no-such.pnbr", "-o", "x.exr"], "no-such.pnbr"),
        (
            vec!["merge", s, "-o", "x.exr"],
            "not a valid penumbra checkpoint or part file",
        ),
    ] {
        let e = err_line(&run(&args));
        assert!(e.contains(expected), "{args:?}: {e}");
        // One error line (clap adds its "For more information, try '--help'." hint).
        assert_eq!(
            e.lines().filter(|l| l.starts_with("error")).count(),
            1,
            "{args:?}: {e}"
        );
        assert!(
            e.lines().next().unwrap_or("").contains(expected),
            "{args:?}: {e}"
        );
    }
    // Spectral mode (issue 43): its parts merge to the one-process spectral render bit for
    // bit, and a spectral part does not merge with an RGB one (the mode is part of the
    // scene's identity).
    let spectral = |i: u32| dir.join(format!("s{i}.pnbr")).display().to_string();
    let (a, b) = split_and_whole("s", &["--mode", "spectral"]);
    assert!(
        a.rgb == b.rgb,
        "merged spectral parts differ from the one-process render"
    );
    assert!(
        a.rgb != rgb_single.rgb,
        "spectral and RGB renders are the same image"
    );
    let e = err_line(&run(&["merge", &spectral(0), &p(1), "-o", "x.exr"]));
    assert!(e.contains("or --mode"), "{e}");
}

/// A part whose checkpoints cannot be written says so: every failed periodic write is
/// counted and the last error kept (a part rendering for hours must not lose its progress
/// silently). Each failure costs the retry delays (0.5 s).
#[test]
fn failed_part_checkpoints_are_counted_and_reported() {
    let (job, hash) = load_with_hash("scenes/cornell-box.xml", &[("res", "16")]);
    let pass = pass_spp(16, 16) as u64;
    let plan = PartPlan {
        index: 0,
        count: 1,
        plan_spp: 3 * pass,
        start_spp: 0,
    };
    let dir = std::env::temp_dir().join(format!("penumbra-part-ckpt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let run = |path: PathBuf| {
        let settings = PartSettings {
            seed: SEED,
            threads: None,
            scene_hash: hash,
            stop: None,
            checkpoint: Some(Checkpointing {
                path,
                every: std::time::Duration::ZERO,
            }),
        };
        render_part_with(&job, &plan, &settings, None, &|_| {}).expect("part renders")
    };
    // after the first and the second of three passes
    let bad = run(dir.join("no-such-dir").join("part.ckpt"));
    assert_eq!(bad.checkpoint_failures, 2);
    let e = bad.checkpoint_error.expect("the last failure is kept");
    assert!(e.contains("no-such-dir"), "{e}");
    let good = run(dir.join("part.ckpt"));
    let written = dir.join("part.ckpt").exists();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!((good.checkpoint_failures, good.checkpoint_error), (0, None));
    assert!(written);
}
