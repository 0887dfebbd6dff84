//! The interactive comparison page (`penumbra report`, and the validation study's page): a
//! self-contained static folder that opens from disk, with no network.
//!
//! `index.html` holds the viewer (HTML, CSS and JavaScript, from `report/page.html`), and
//! `data.js` the data: `window.PENUMBRA_REPORT = {...}`, one JSON object with, per scene,
//! every image as half floats (IEEE 754 binary16, little endian, RGB interleaved, rows from
//! the top, base64) times a power-of-two `scale`, its samples per pixel and time, and its
//! metrics against the reference exactly as `compare --json` gives them. The page decodes
//! the floats and applies exposure, tone mapping and error maps itself, so an exposure change
//! is exact on the stored values (no 8-bit images per exposure). Half floats keep 11
//! significant bits (relative error ≤ 2⁻¹¹); the scale keeps an image whose maximum exceeds
//! the half range (65504) finite. A 512² comparison of three images is about 6.3 MB.
//! Plots (PNG) are copied into `plots/`.
//!
//! JSON, not a binary file beside the page: browsers refuse `fetch` of local files, but load
//! `<script src>` from disk.

use crate::error::{Error, Result};
use crate::io::exr::RgbImage;
use crate::study::compare;
use base64::Engine as _;
use half::f16;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The page's HTML, CSS and JavaScript.
const PAGE: &str = include_str!("report/page.html");

/// The largest finite half float.
const HALF_MAX: f32 = 65504.0;

/// One image of a comparison.
#[derive(Clone, Debug)]
pub struct ReportImage {
    pub name: String,
    pub image: RgbImage,
    /// Samples per pixel (for the z-test and the table), if known.
    pub spp: Option<f64>,
    /// Render time in seconds, if known.
    pub seconds: Option<f64>,
}

impl ReportImage {
    /// An image read from an OpenEXR file: spp and time from its header attributes
    /// (`spp`, `render_time_seconds` as penumbra writes them, `render_seconds` as
    /// validation/mitsuba/render_reference.py writes them).
    pub fn from_file(path: &Path) -> Result<ReportImage> {
        let image = crate::io::exr::read(path)?;
        let seconds = ["render_time_seconds", "render_seconds"]
            .iter()
            .find_map(|k| image.attributes.get(*k))
            .and_then(|s| s.trim().parse::<f64>().ok())
            .filter(|s| s.is_finite() && *s >= 0.0);
        Ok(ReportImage {
            name: path.file_name().map_or_else(
                || path.display().to_string(),
                |n| n.to_string_lossy().into(),
            ),
            spp: image.spp(),
            seconds,
            image,
        })
    }
}

/// A plot shown under the images.
#[derive(Clone, Debug)]
pub struct ReportPlot {
    pub caption: String,
    /// A PNG file, copied into the report's `plots/`.
    pub path: PathBuf,
}

/// One scene: a reference and the images compared with it.
#[derive(Clone, Debug)]
pub struct ReportScene {
    pub name: String,
    pub reference: ReportImage,
    pub images: Vec<ReportImage>,
    pub plots: Vec<ReportPlot>,
    /// Lines of text shown above the table (e.g. the validation verdict).
    pub notes: Vec<String>,
}

/// What [`write_report`] wrote.
#[derive(Clone, Debug)]
pub struct ReportSummary {
    pub index: PathBuf,
    /// Bytes of every file written.
    pub bytes: u64,
}

/// Half floats of `rgb` / `scale` (little endian, interleaved) and the scale: the smallest
/// power of two ≥ 1 that brings the largest finite magnitude within the half range.
pub fn encode_half(rgb: &[[f32; 3]]) -> (Vec<u8>, f32) {
    let max = rgb
        .iter()
        .flatten()
        .filter(|v| v.is_finite())
        .fold(0.0f32, |m, v| m.max(v.abs()));
    let mut scale = 1.0f32;
    while max / scale > HALF_MAX {
        scale *= 2.0;
    }
    let mut bytes = Vec::with_capacity(rgb.len() * 6);
    for v in rgb.iter().flatten() {
        bytes.extend_from_slice(&f16::from_f32(v / scale).to_le_bytes());
    }
    (bytes, scale)
}

/// The values [`encode_half`] stored, as the page decodes them.
pub fn decode_half(bytes: &[u8], scale: f32) -> Vec<f32> {
    bytes
        .chunks_exact(2)
        .map(|b| f16::from_le_bytes([b[0], b[1]]).to_f32() * scale)
        .collect()
}

#[derive(Serialize)]
struct ImageJson<'a> {
    name: &'a str,
    spp: Option<f64>,
    seconds: Option<f64>,
    /// base64 of the half floats.
    data: String,
    scale: f32,
    /// `compare --json` of this image against the reference (None for the reference).
    metrics: Option<compare::ComparisonJson<'a>>,
}

#[derive(Serialize)]
struct PlotJson {
    caption: String,
    src: String,
}

#[derive(Serialize)]
struct SceneJson<'a> {
    name: &'a str,
    width: usize,
    height: usize,
    /// The reference first, then the images.
    images: Vec<ImageJson<'a>>,
    plots: Vec<PlotJson>,
    notes: &'a [String],
}

/// The JSON object of `data.js`.
#[derive(Serialize)]
struct ReportJson<'a> {
    title: &'a str,
    generator: String,
    alpha: f64,
    scenes: Vec<SceneJson<'a>>,
}

fn output_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Writes the page for `scenes` into the folder `dir` (created if needed): `index.html`,
/// `data.js` and `plots/`. Every image must have its scene's reference's size.
pub fn write_report(dir: &Path, title: &str, scenes: &[ReportScene]) -> Result<ReportSummary> {
    if scenes.is_empty() {
        return Err(Error::Invalid("a report needs at least one scene".into()));
    }
    let alpha = crate::study::validation::ALPHA;
    std::fs::create_dir_all(dir.join("plots")).map_err(|e| output_error(dir, e))?;
    let mut bytes = 0u64;
    let mut scene_json = Vec::with_capacity(scenes.len());
    let mut plot_count = 0usize;
    for scene in scenes {
        let r = &scene.reference;
        let mut images = Vec::with_capacity(scene.images.len() + 1);
        let (data, scale) = encode_half(&r.image.rgb);
        images.push(ImageJson {
            name: &r.name,
            spp: r.spp,
            seconds: r.seconds,
            data: base64::engine::general_purpose::STANDARD.encode(data),
            scale,
            metrics: None,
        });
        for img in &scene.images {
            let c = compare::compare(&img.image, &r.image, img.spp, r.spp, alpha).map_err(|e| {
                Error::Invalid(format!(
                    "{}: {} against {}: {e}",
                    scene.name, img.name, r.name
                ))
            })?;
            let (data, scale) = encode_half(&img.image.rgb);
            images.push(ImageJson {
                name: &img.name,
                spp: img.spp,
                seconds: img.seconds,
                data: base64::engine::general_purpose::STANDARD.encode(data),
                scale,
                metrics: Some(c.to_json(&img.name, &r.name, alpha, None)),
            });
        }
        let mut plots = Vec::with_capacity(scene.plots.len());
        for p in &scene.plots {
            let file = format!("plot-{plot_count}.png");
            plot_count += 1;
            let dest = dir.join("plots").join(&file);
            bytes += std::fs::copy(&p.path, &dest).map_err(|e| Error::Io {
                path: p.path.clone(),
                cause: e,
            })?;
            plots.push(PlotJson {
                caption: p.caption.clone(),
                src: format!("plots/{file}"),
            });
        }
        scene_json.push(SceneJson {
            name: &scene.name,
            width: r.image.width,
            height: r.image.height,
            images,
            plots,
            notes: &scene.notes,
        });
    }
    let json = ReportJson {
        title,
        generator: format!("penumbra {}", crate::VERSION),
        alpha,
        scenes: scene_json,
    };
    let data = format!(
        "window.PENUMBRA_REPORT = {};\n",
        serde_json::to_string(&json).map_err(|e| output_error(dir, e))?
    );
    let data_path = dir.join("data.js");
    std::fs::write(&data_path, &data).map_err(|e| output_error(&data_path, e))?;
    let index = dir.join("index.html");
    let page = PAGE.replace("{{TITLE}}", &html_escape(title));
    std::fs::write(&index, &page).map_err(|e| output_error(&index, e))?;
    bytes += (data.len() + page.len()) as u64;
    Ok(ReportSummary { index, bytes })
}

/// The JSON object a `data.js` holds (for tests and tools).
pub fn read_data_js(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: path.to_path_buf(),
        cause: e,
    })?;
    let bad = || Error::Invalid(format!("{}: not a penumbra report data.js", path.display()));
    let json = text
        .trim()
        .strip_prefix("window.PENUMBRA_REPORT = ")
        .and_then(|s| s.strip_suffix(';'))
        .ok_or_else(bad)?;
    serde_json::from_str(json).map_err(|_| bad())
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_round_trip_is_exact_for_half_values_and_within_half_precision_otherwise() {
        // every finite half float survives exactly (scale 1: none exceeds the half range)
        let halves: Vec<[f32; 3]> = (0..=u16::MAX)
            .map(|b| f16::from_bits(b).to_f32())
            .filter(|v| v.is_finite())
            .map(|v| [v, -v, v * 0.5])
            .collect();
        let (bytes, scale) = encode_half(&halves);
        assert_eq!(scale, 1.0);
        let back = decode_half(&bytes, scale);
        for (p, q) in halves.iter().zip(back.chunks_exact(3)) {
            assert_eq!(p[0], q[0]);
            assert_eq!(p[1], q[1]);
        }
        // arbitrary values in the normal half range: relative error <= 2^-11 (round to
        // nearest of an 11-bit significand)
        let values: Vec<[f32; 3]> = (1..800)
            .map(|i| {
                let x = 1e-4 * 1.0137f32.powi(i);
                [x, x * 3.3, 1.0 / x]
            })
            .collect();
        let (bytes, scale) = encode_half(&values);
        let back = decode_half(&bytes, scale);
        for (v, b) in values.iter().flatten().zip(&back) {
            assert!(((b - v) / v).abs() <= 2f32.powi(-11), "{v} -> {b}");
        }
        // beyond the half range: a power-of-two scale keeps the values finite and exact to
        // half precision
        let big = vec![[1e6f32, 3.0, 70000.0], [-2e5, 0.5, 1.0]];
        let (bytes, scale) = encode_half(&big);
        assert_eq!(scale, 16.0); // 1e6 / 16 = 62500 <= 65504 < 1e6 / 8
        for (v, b) in big.iter().flatten().zip(decode_half(&bytes, scale)) {
            assert!(
                b.is_finite() && ((b - v) / v).abs() <= 2f32.powi(-11),
                "{v} -> {b}"
            );
        }
        // non-finite values stay non-finite and do not set the scale
        let odd = vec![[f32::INFINITY, f32::NAN, 1.0]];
        let (bytes, scale) = encode_half(&odd);
        let back = decode_half(&bytes, scale);
        assert_eq!(scale, 1.0);
        assert!(back[0].is_infinite() && back[1].is_nan() && back[2] == 1.0);
    }
}
