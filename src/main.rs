//! The `penumbra` command line.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use penumbra::io::exr::{self, Attribute, RgbImage};
use penumbra::render::{render, RenderSettings};
use penumbra::scene::Scene;
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::PathBuf;

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
    /// No progress bar and no summary line.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_define(s: &str) -> Result<(String, String)> {
    match s.split_once('=') {
        Some((k, v)) if !k.is_empty() => Ok((k.to_string(), v.to_string())),
        _ => bail!("-D expects NAME=VALUE, got '{s}'"),
    }
}

fn run_render(args: RenderArgs) -> Result<()> {
    let defines = args
        .define
        .iter()
        .map(|d| parse_define(d))
        .collect::<Result<Vec<_>>>()?;
    let scene = Scene::load(&args.scene, &defines)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let spp = args.spp.unwrap_or(scene.sample_count);
    if spp == 0 {
        bail!("--spp must be at least 1");
    }
    let settings = RenderSettings {
        spp,
        seed: args.seed.unwrap_or(scene.seed),
        threads: args.threads,
        first_sample: 0,
    };
    let total = (scene.width * scene.height) as u64 * spp as u64;
    let bar = if args.quiet || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        b.set_style(
            ProgressStyle::with_template(
                "{bar:40} {percent:>3}% {elapsed_precise} ETA {eta_precise}",
            )
            .context("progress bar template")?,
        );
        b
    };
    let out = render(&scene, &settings, &|done, _| bar.set_position(done))?;
    bar.finish_and_clear();
    let stats = out.stats;
    let image = RgbImage {
        width: scene.width,
        height: scene.height,
        rgb: out.film.image(),
        variance: args.variance.then(|| out.film.sample_variance()),
        attributes: BTreeMap::new(),
    };
    let spp_attr = i32::try_from(spp).map_or(Attribute::Float(spp as f64), Attribute::Int);
    exr::write(
        &args.output,
        &image,
        &[
            ("spp", spp_attr),
            ("seed", Attribute::Text(settings.seed.to_string())),
            ("render_time_seconds", Attribute::Float(stats.seconds)),
            (
                "penumbra_version",
                Attribute::Text(penumbra::VERSION.to_string()),
            ),
            (
                "nonfinite_samples",
                Attribute::Float(stats.nonfinite as f64),
            ),
        ],
    )?;
    if let Some(png) = &args.preview {
        penumbra::io::png::write_preview(png, scene.width, scene.height, &image.rgb, 1.0)?;
    }
    if !args.quiet {
        eprintln!(
            "{}x{}, {} spp, {:.2} s, {:.2} Mpath/s, {} non-finite samples dropped -> {}",
            scene.width,
            scene.height,
            spp,
            stats.seconds,
            stats.mpaths_per_second(),
            stats.nonfinite,
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
