//! `penumbra report`: the page's data against `compare --json` (the metrics the page shows
//! are the CLI's, value for value), the images it stores against the EXR files, the size
//! budget, and one-line errors. The page itself is tested in a browser by
//! tests/browser/test_report.py.

use penumbra::io::exr::{self, Attribute, RgbImage};
use penumbra::study::report::{decode_half, read_data_js};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-report-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A deterministic noisy image (incompressible, like a render's noise) with its variance.
fn noisy(width: usize, height: usize, seed: u64, spp: i32, path: &Path) {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f32 / (1u64 << 53) as f32
    };
    let rgb = (0..width * height)
        .map(|_| [next() * 2.0, next(), next() * 0.5])
        .collect();
    let variance = Some(
        (0..width * height)
            .map(|_| [next(), next(), next()])
            .collect(),
    );
    let image = RgbImage {
        width,
        height,
        rgb,
        variance,
        attributes: BTreeMap::new(),
    };
    exr::write(
        path,
        &image,
        &[
            ("spp", Attribute::Int(spp)),
            ("render_time_seconds", Attribute::Float(1.5)),
        ],
    )
    .unwrap();
}

fn run(args: &[&std::ffi::OsStr]) -> std::process::Output {
    bin().args(args).output().unwrap()
}

#[test]
fn page_data_holds_the_images_and_the_metrics_of_compare_json() {
    let dir = tmpdir("metrics");
    let (r, a, b) = (dir.join("ref.exr"), dir.join("a.exr"), dir.join("b.exr"));
    noisy(40, 30, 1, 4096, &r);
    noisy(40, 30, 2, 16, &a);
    noisy(40, 30, 3, 64, &b);
    let out = dir.join("page");
    let o = run(&[
        "report".as_ref(),
        "--reference".as_ref(),
        r.as_os_str(),
        a.as_os_str(),
        b.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("index.html").is_file());
    let data = read_data_js(&out.join("data.js")).unwrap();
    let scene = &data["scenes"][0];
    assert_eq!(
        (scene["width"].as_u64(), scene["height"].as_u64()),
        (Some(40), Some(30))
    );
    let images = scene["images"].as_array().unwrap();
    assert_eq!(images.len(), 3);
    assert!(images[0]["metrics"].is_null());
    for (json, path) in images.iter().zip([&r, &a, &b]) {
        // the stored half floats are the file's values to half precision
        let file = exr::read(path).unwrap();
        use base64::Engine as _;
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(json["data"].as_str().unwrap())
            .unwrap();
        let values = decode_half(&bytes, json["scale"].as_f64().unwrap() as f32);
        assert_eq!(values.len(), 40 * 30 * 3);
        for (v, f) in values.iter().zip(file.rgb.iter().flatten()) {
            assert!(
                (v - f).abs() <= f.abs() * 2f32.powi(-11) + 6e-8,
                "{f} stored as {v}"
            );
        }
        assert_eq!(json["seconds"].as_f64(), Some(1.5));
    }
    // the metrics are what `compare --json` prints, key for key, value for value
    for (json, path) in images[1..].iter().zip([&a, &b]) {
        let o = run(&[
            "compare".as_ref(),
            path.as_os_str(),
            r.as_os_str(),
            "--json".as_ref(),
        ]);
        assert!(o.status.success());
        let cli: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let mut ours = json["metrics"].clone();
        // compare names the files by the paths it was given; the page by their names
        for (key, p) in [("a", path), ("b", &r)] {
            assert_eq!(
                ours[key].as_str(),
                Some(p.file_name().unwrap().to_str().unwrap())
            );
            ours[key] = cli[key].clone();
        }
        assert_eq!(ours, cli);
        assert!(cli["z_test"]["tests"].as_u64() == Some(40 * 30 * 3));
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_512_comparison_of_three_images_stays_under_10_mb() {
    let dir = tmpdir("size");
    let paths: Vec<PathBuf> = (0..4).map(|k| dir.join(format!("{k}.exr"))).collect();
    for (k, p) in paths.iter().enumerate() {
        noisy(512, 512, k as u64 + 10, 64, p);
    }
    let out = dir.join("page");
    let mut args: Vec<&std::ffi::OsStr> = vec!["report".as_ref(), "--reference".as_ref()];
    args.extend(paths.iter().map(|p| p.as_os_str()));
    args.extend(["-o".as_ref(), out.as_os_str()]);
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes: u64 = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum();
    // the reference and three images: 4 x 512² x 3 half floats, base64: 8.4 MB
    assert!(bytes < 10_000_000, "{bytes} bytes");
    assert!(
        bytes > 8_000_000,
        "{bytes} bytes: are all four images stored?"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_input_is_one_error_line() {
    let dir = tmpdir("errors");
    let (r, small) = (dir.join("ref.exr"), dir.join("small.exr"));
    noisy(8, 8, 1, 16, &r);
    noisy(4, 8, 2, 16, &small);
    let out = dir.join("page");
    for (args, expect) in [
        (
            vec![
                r.as_os_str(),
                dir.join("missing.exr").into_os_string().leak(),
            ],
            "missing.exr",
        ),
        (vec![r.as_os_str(), small.as_os_str()], "differ in size"),
    ] {
        let mut all: Vec<&std::ffi::OsStr> = vec!["report".as_ref(), "--reference".as_ref()];
        all.extend(args);
        all.extend(["-o".as_ref(), out.as_os_str()]);
        let o = run(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success());
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.starts_with("error: ") && err.contains(expect), "{err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
