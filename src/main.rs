//! The `penumbra` command line.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use penumbra::io::exr::{self, Attribute, RgbImage};
use penumbra::progressive;
use penumbra::scene::Scene;
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "A physically based path tracer for Mitsuba 3 scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a Mitsuba 3 XML scene to an OpenEXR image.
    Render(RenderArgs),
}

#[derive(clap::Args)]
struct RenderArgs {
    /// The scene file (Mitsuba 3 XML).
    scene: PathBuf,
    /// Output image (OpenEXR, 32-bit float linear RGB).
    #[arg(short, long, default_value = "out.exr")]
    output: PathBuf,
    /// Samples per pixel (overrides the scene's sample_count).
    #[arg(long)]
    spp: Option<u32>,
    /// Random seed (overrides the sampler's seed). Same seed, same image, at any thread count.
    #[arg(long)]
    seed: Option<u64>,
    /// Set a scene parameter declared with <default name=...>, like Mitsuba's -D.
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    define: Vec<String>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Also write a tone-mapped sRGB PNG preview.
    #[arg(long, value_name = "PNG")]
    preview: Option<PathBuf>,
    /// Add per-pixel per-sample variance channels (variance.R/G/B) to the EXR.
    #[arg(long)]
    variance: bool,
    /// Stop after this much wall time (e.g. 90s, 10m, 1.5h; a plain number is seconds).
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    time_limit: Option<Duration>,
    /// Stop once the estimated relative standard error of the image mean (worst channel) is
    /// at most this (e.g. 0.01); checked from 16 spp on.
    #[arg(long, value_name = "REL")]
    target_rel_error: Option<f64>,
    /// Apply --target-rel-error to the mean over pixels of each pixel's relative standard
    /// error (of luminance) instead of the image mean.
    #[arg(long, requires = "target_rel_error")]
    target_per_pixel: bool,
    /// Checkpoint file (default: the output path with .ckpt appended).
    #[arg(long, value_name = "PATH")]
    checkpoint: Option<PathBuf>,
    /// Write the running sums to the checkpoint this often (and at the end).
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    checkpoint_every: Option<Duration>,
    /// Continue the render saved in the checkpoint (same scene, seed and penumbra version).
    #[arg(long)]
    resume: bool,
    /// Write render statistics as JSON.
    #[arg(long, value_name = "JSON")]
    stats: Option<PathBuf>,
    /// No progress bar and no summary line.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_duration(s: &str) -> std::result::Result<Duration, String> {
    let (num, unit) = match s.find(|c: char| c.is_ascii_alphabetic()) {
        Some(i) => s.split_at(i),
        None => (s, "s"),
    };
    let factor = match unit {
        "s" => 1.0,
        "m" | "min" => 60.0,
        "h" => 3600.0,
        _ => return Err(format!("unknown time unit '{unit}' (use s, m or h)")),
    };
    match num.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 && x * factor < 1e9 => {
            Ok(Duration::from_secs_f64(x * factor))
        }
        _ => Err(format!("'{s}' is not a duration (e.g. 90s, 10m, 1.5h)")),
    }
}

fn parse_define(s: &str) -> Result<(String, String)> {
    match s.split_once('=') {
        Some((k, v)) if !k.is_empty() => Ok((k.to_string(), v.to_string())),
        _ => bail!("-D expects NAME=VALUE, got '{s}'"),
    }
}

/// Render statistics as a flat JSON object (numbers and plain strings only).
fn stats_json(fields: &[(&str, String)]) -> String {
    let body: Vec<String> = fields
        .iter()
        .map(|(k, v)| format!("  \"{k}\": {v}"))
        .collect();
    format!("{{\n{}\n}}\n", body.join(",\n"))
}

fn run_render(args: RenderArgs) -> Result<()> {
    let defines = args
        .define
        .iter()
        .map(|d| parse_define(d))
        .collect::<Result<Vec<_>>>()?;
    let desc = Scene::load_description(&args.scene, &defines)?;
    let scene_hash = progressive::scene_hash(&desc);
    let scene = penumbra::scene::build::build(&desc)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let spp = args.spp.unwrap_or(scene.sample_count);
    if spp == 0 {
        bail!("--spp must be at least 1");
    }
    if let Some(t) = args.target_rel_error {
        if !(t > 0.0 && t.is_finite()) {
            bail!("--target-rel-error must be a positive number, got {t}");
        }
    }
    let seed = args.seed.unwrap_or(scene.seed);
    let checkpoint_path = args.checkpoint.clone().unwrap_or_else(|| {
        let mut p = args.output.clone().into_os_string();
        p.push(".ckpt");
        PathBuf::from(p)
    });
    let checkpointing = (args.checkpoint_every.is_some()
        || args.checkpoint.is_some()
        || args.resume)
        .then(|| progressive::Checkpointing {
            path: checkpoint_path.clone(),
            every: args.checkpoint_every.unwrap_or(Duration::from_secs(300)),
        });
    let resume = if args.resume {
        Some(progressive::Checkpoint::read(
            &checkpoint_path,
            scene.filter,
        )?)
    } else {
        None
    };
    let settings = progressive::ProgressiveSettings {
        spp,
        seed,
        threads: args.threads,
        time_limit: args.time_limit,
        target_rel_error: args.target_rel_error.map(|t| {
            let kind = if args.target_per_pixel {
                progressive::ErrorTarget::PerPixel
            } else {
                progressive::ErrorTarget::ImageMean
            };
            (t, kind)
        }),
        checkpoint: checkpointing,
        scene_hash,
    };
    let pixels = (scene.width * scene.height) as u64;
    let bar = if args.quiet || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let b =
            ProgressBar::with_draw_target(Some(pixels * spp as u64), ProgressDrawTarget::stderr());
        b.set_style(
            ProgressStyle::with_template(
                "{bar:40} {percent:>3}% {elapsed_precise} ETA {eta_precise}",
            )
            .context("progress bar template")?,
        );
        b
    };
    let (progress, reason) = progressive::render_progressive(&scene, &settings, resume, &|p| {
        bar.set_position(p.samples * pixels)
    })?;
    bar.finish_and_clear();
    let stats = progress.stats;
    let spp_done = progress.samples;
    let image = RgbImage {
        width: scene.width,
        height: scene.height,
        rgb: progress.film.image(),
        variance: args.variance.then(|| progress.film.sample_variance()),
        attributes: BTreeMap::new(),
    };
    let secs = stats.seconds.max(1e-9);
    let rays_per_s = stats.path.rays as f64 / secs;
    let mean_len = stats.path.bounces as f64 / stats.paths.max(1) as f64;
    let rr_frac = stats.path.rr_terminated as f64 / stats.paths.max(1) as f64;
    let reason_text = match reason {
        progressive::StopReason::SppReached => "spp reached",
        progressive::StopReason::TimeLimit => "time limit",
        progressive::StopReason::TargetError => "target error reached",
    };
    let spp_attr =
        i32::try_from(spp_done).map_or(Attribute::Float(spp_done as f64), Attribute::Int);
    exr::write(
        &args.output,
        &image,
        &[
            ("spp", spp_attr),
            ("seed", Attribute::Text(seed.to_string())),
            ("render_time_seconds", Attribute::Float(stats.seconds)),
            (
                "penumbra_version",
                Attribute::Text(penumbra::VERSION.to_string()),
            ),
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
        ],
    )?;
    if let Some(png) = &args.preview {
        penumbra::io::png::write_preview(png, scene.width, scene.height, &image.rgb, 1.0)?;
    }
    if let Some(path) = &args.stats {
        let json = stats_json(&[
            ("width", scene.width.to_string()),
            ("height", scene.height.to_string()),
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
            ("penumbra_version", format!("\"{}\"", penumbra::VERSION)),
        ]);
        std::fs::write(path, json).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if !args.quiet {
        eprintln!(
            "{}x{}, {} spp, {:.2} s, {:.2} Mpath/s, {:.2} Mray/s, mean path length {:.2}, RR ended {:.1}%, \
             {} non-finite samples dropped, stopped: {} -> {}",
            scene.width,
            scene.height,
            spp_done,
            stats.seconds,
            stats.paths as f64 / secs / 1e6,
            rays_per_s / 1e6,
            mean_len,
            100.0 * rr_frac,
            stats.nonfinite,
            reason_text,
            args.output.display()
        );
    }
    Ok(())
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => run_render(args),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
