//! What renders and merges write: the check that outputs are writable before any work, and a
//! film as EXR (with its header attributes), PNG preview and JSON statistics.

use anyhow::{Context, Result};
use penumbra::io::exr::{self, Attribute, RgbImage};
use std::collections::BTreeMap;
use std::path::Path;

/// Render statistics as a flat JSON object (numbers and plain strings only).
fn stats_json(fields: &[(&str, String)]) -> String {
    let body: Vec<String> = fields
        .iter()
        .map(|(k, v)| format!("  \"{k}\": {v}"))
        .collect();
    format!("{{\n{}\n}}\n", body.join(",\n"))
}

/// The lane engine's utilisation for the summary line (empty when it did not run).
pub(super) fn lane_summary(lanes: &penumbra::integrator::lanes::LaneStats) -> String {
    if lanes.iterations == 0 {
        return String::new();
    }
    format!(
        " (lanes busy: {:.1}% at intersection, {:.1}% at scattering)",
        100.0 * lanes.utilisation(),
        100.0 * lanes.scatter_utilisation()
    )
}

/// The lane engine's counters as JSON fields (none when it did not run): utilisation at
/// the intersection and scatter steps (active lanes / width), iterations, and the
/// histograms of active lanes per iteration and of active lanes by path depth.
fn lane_json(lanes: &penumbra::integrator::lanes::LaneStats) -> Vec<(&'static str, String)> {
    if lanes.iterations == 0 {
        return Vec::new();
    }
    let list = |v: &[u64]| {
        let items: Vec<String> = v.iter().map(|x| x.to_string()).collect();
        format!("[{}]", items.join(", "))
    };
    vec![
        ("lane_width", lanes.width.to_string()),
        ("lane_iterations", lanes.iterations.to_string()),
        ("lane_utilisation", format!("{:.6}", lanes.utilisation())),
        (
            "lane_scatter_utilisation",
            format!("{:.6}", lanes.scatter_utilisation()),
        ),
        ("lane_iterations_by_active_lanes", list(&lanes.by_active)),
        ("lane_active_lanes_by_depth", list(&lanes.by_depth)),
    ]
}

/// Fails unless every one of `outputs` (path, what it is) can be written: its directory
/// exists and takes a new file. Checked before any scene data is loaded, so that a long
/// render never ends in an unwritable path.
pub(super) fn check_outputs(outputs: &[(&Path, &str)]) -> Result<()> {
    for (path, what) in outputs {
        penumbra::io::atomic::check_writable(path)
            .with_context(|| format!("{}: cannot write {what}", path.display()))?;
    }
    Ok(())
}

/// The EXR header attributes every render writes: spp, seed, time and penumbra's version.
pub(super) fn render_attributes(
    spp: u64,
    seed: u64,
    seconds: f64,
) -> Vec<(&'static str, Attribute)> {
    let spp_attr = i32::try_from(spp).map_or(Attribute::Float(spp as f64), Attribute::Int);
    vec![
        ("spp", spp_attr),
        ("seed", Attribute::Text(seed.to_string())),
        ("render_time_seconds", Attribute::Float(seconds)),
        (
            "penumbra_version",
            Attribute::Text(penumbra::VERSION.to_string()),
        ),
    ]
}

/// What [`write_image`] writes: a render's film as EXR (+ variance), preview and statistics.
pub(super) struct ImageOutput<'a> {
    pub(super) output: &'a std::path::Path,
    pub(super) film: &'a penumbra::film::Film,
    pub(super) spp: u64,
    pub(super) seed: u64,
    pub(super) stats: penumbra::render::RenderStats,
    pub(super) reason: &'a str,
    pub(super) variance: bool,
    pub(super) preview: Option<&'a std::path::Path>,
    pub(super) stats_json_path: Option<&'a std::path::Path>,
    pub(super) quiet: bool,
}

pub(super) fn write_image(o: &ImageOutput) -> Result<()> {
    let (width, height) = (o.film.width, o.film.height);
    let stats = o.stats;
    let spp_done = o.spp;
    let seed = o.seed;
    let reason_text = o.reason;
    let image = RgbImage {
        width,
        height,
        rgb: o.film.image(),
        variance: o.variance.then(|| o.film.sample_variance()),
        attributes: BTreeMap::new(),
    };
    let secs = stats.seconds.max(1e-9);
    let rays_per_s = stats.path.rays as f64 / secs;
    let mean_len = stats.path.bounces as f64 / stats.paths.max(1) as f64;
    let rr_frac = stats.path.rr_terminated as f64 / stats.paths.max(1) as f64;
    let mut attributes = render_attributes(spp_done, seed, stats.seconds);
    attributes.extend([
        (
            "nonfinite_samples",
            Attribute::Float(stats.nonfinite as f64),
        ),
        ("rays_per_second", Attribute::Float(rays_per_s)),
        (
            "paths_per_second",
            Attribute::Float(stats.paths as f64 / secs),
        ),
        ("mean_path_length", Attribute::Float(mean_len)),
        ("rr_terminated_fraction", Attribute::Float(rr_frac)),
        ("stop_reason", Attribute::Text(reason_text.into())),
    ]);
    exr::write(o.output, &image, &attributes)?;
    if let Some(png) = o.preview {
        penumbra::io::png::write_preview(png, width, height, &image.rgb, 1.0)?;
    }
    if let Some(path) = o.stats_json_path {
        let mut fields = vec![
            ("width", width.to_string()),
            ("height", height.to_string()),
            ("spp", spp_done.to_string()),
            ("seed", seed.to_string()),
            ("stop_reason", format!("\"{reason_text}\"")),
            ("seconds", format!("{:.6}", stats.seconds)),
            ("paths", stats.paths.to_string()),
            (
                "paths_per_second",
                format!("{:.1}", stats.paths as f64 / secs),
            ),
            ("rays", stats.path.rays.to_string()),
            ("rays_per_second", format!("{rays_per_s:.1}")),
            ("mean_path_length", format!("{mean_len:.6}")),
            ("rr_terminated_fraction", format!("{rr_frac:.6}")),
            ("nonfinite_samples", stats.nonfinite.to_string()),
            ("engine", format!("\"{}\"", stats.engine)),
            ("penumbra_version", format!("\"{}\"", penumbra::VERSION)),
        ];
        fields.extend(lane_json(&stats.lanes));
        let json = stats_json(&fields);
        penumbra::io::atomic::write_bytes(path, json.as_bytes())
            .with_context(|| format!("{}: cannot write statistics", path.display()))?;
    }
    if !o.quiet {
        eprintln!(
            "{}x{}, {} spp, {:.2} s, engine {}{}, {:.2} Mpath/s, {:.2} Mray/s, mean path length {:.2}, \
             RR ended {:.1}%, {} non-finite samples dropped, stopped: {} -> {}",
            width,
            height,
            spp_done,
            stats.seconds,
            stats.engine,
            lane_summary(&stats.lanes)
                + &stats
                    .light_paths
                    .map(|x| {
                        if x == 0.0 {
                            " (no light subpaths: the path tracer's estimator)".to_string()
                        } else {
                            format!(" (light subpaths in {:.1}% of samples)", 100.0 * x)
                        }
                    })
                    .unwrap_or_default(),
            stats.paths as f64 / secs / 1e6,
            rays_per_s / 1e6,
            mean_len,
            100.0 * rr_frac,
            stats.nonfinite,
            reason_text,
            o.output.display()
        );
    }
    Ok(())
}
