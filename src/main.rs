//! The `penumbra` command line.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use penumbra::io::exr::{self, Attribute, RgbImage};
use penumbra::progressive;
use penumbra::render::Job;
use penumbra::scene::Scene;
use penumbra::study::compare;
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "A physically based path tracer for Mitsuba 3 scenes",
    after_help = "Environment: PENUMBRA_LIMITS=name=value,... raises (or lowers) the limits on \
                  input a large scene may exceed: render_pixels, image_pixels, image_bytes, \
                  mesh_bytes, shape_bytes, vol_bytes, radiosity_rays (e.g. \
                  PENUMBRA_LIMITS=render_pixels=2^28,mesh_bytes=32G; see docs/usage.md, Limits)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a Mitsuba 3 XML scene to an OpenEXR image.
    Render(RenderArgs),
    /// Merge the part files of a render split with `render --part i/N` into its image,
    /// bit-identical to the render made in one process.
    Merge(MergeArgs),
    /// Compare image A with the reference B: error metrics, z-test, false-colour diff.
    Compare(CompareArgs),
    /// Render a ladder of sample counts against a reference: error vs. spp and time, slope,
    /// efficiency; optionally over several seeds and a swept scene parameter.
    Converge(ConvergeArgs),
    /// Write an interactive HTML page comparing images with a reference: flip, zoom to
    /// single pixels, change exposure, error maps, metrics, convergence plots. A static
    /// folder that opens from disk.
    Report(ReportArgs),
}

#[derive(clap::Args)]
struct ReportArgs {
    /// The reference image (OpenEXR).
    #[arg(long, value_name = "EXR")]
    reference: PathBuf,
    /// The images to compare with it (OpenEXR, the reference's size); keys 2..9 show them.
    #[arg(required = true, value_name = "EXR")]
    images: Vec<PathBuf>,
    /// The folder to write (index.html, data.js, plots/).
    #[arg(short, long, default_value = "report")]
    output: PathBuf,
    /// The page's title (default: the reference's file name).
    #[arg(long)]
    title: Option<String>,
    /// Show a plot under the images: a PNG, or the output folder of `penumbra converge`
    /// (its converge.png). Repeatable.
    #[arg(long, value_name = "PNG|DIR")]
    plot: Vec<PathBuf>,
}

#[derive(clap::Args)]
struct CompareArgs {
    /// The image to measure (OpenEXR).
    a: PathBuf,
    /// The reference (OpenEXR), e.g. a Mitsuba reference from validation/references/.
    b: PathBuf,
    /// Write a signed false-colour difference image (A − B) with a colour bar, as PNG.
    #[arg(long, value_name = "PNG")]
    diff: Option<PathBuf>,
    /// Half-range of the diff's colour map (default: the 99th percentile of |A − B|).
    #[arg(long, value_name = "R", requires = "diff")]
    diff_range: Option<f64>,
    /// Print the results as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Samples per pixel of A for the z-test (default: its `spp` header attribute).
    #[arg(long, value_name = "N")]
    spp_a: Option<f64>,
    /// Samples per pixel of B for the z-test (default: its `spp` header attribute).
    #[arg(long, value_name = "N")]
    spp_b: Option<f64>,
}

#[derive(clap::Args)]
struct ConvergeArgs {
    /// The scene file (Mitsuba 3 XML).
    scene: PathBuf,
    /// The reference image (OpenEXR) at the scene's resolution; with variance channels and
    /// an `spp` header attribute (as Mitsuba references made by validation/mitsuba have) it
    /// also gives the noise floor and the z-test.
    #[arg(long, value_name = "EXR")]
    reference: PathBuf,
    /// Samples per pixel of the reference (default: its `spp` header attribute).
    #[arg(long, value_name = "N")]
    reference_spp: Option<f64>,
    /// The ladder: cumulative samples per pixel, each step continuing the previous one's
    /// samples (with stratified, multijitter, orthogonal and ldsampler: each step a render
    /// of its own at that count). `a,b,...,n` continues the progression of ratio b/a up to n.
    #[arg(long, value_name = "LIST", default_value = penumbra::study::experiment::DEFAULT_SPP)]
    spp: String,
    /// Independent ladders with seeds s, s+1, ..., s+K-1: mean and spread per step.
    #[arg(long, value_name = "K", default_value_t = 1)]
    seeds: u32,
    /// First seed (default: the sampler's seed).
    #[arg(long)]
    seed: Option<u64>,
    /// Sweep one scene parameter: NAME=v1,v2,... (a <default> of the scene, as -D sets it;
    /// the path integrator's max_depth / rr_depth; or `sampler=independent,stratified,...`).
    #[arg(long, value_name = "NAME=V1,V2,...")]
    sweep: Option<String>,
    /// Set a scene parameter declared with <default name=...>, like Mitsuba's -D.
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    define: Vec<String>,
    /// Where converge.csv, converge.json and converge.png go.
    #[arg(long, value_name = "DIR", default_value = "converge-out")]
    out_dir: PathBuf,
    /// Stop each ladder after the first step that takes this long (seconds): compares
    /// settings of very different cost per sample (e.g. --sweep integrator=path,sppm) over
    /// the same time budget with one long ladder.
    #[arg(long, value_name = "SECONDS")]
    max_seconds: Option<f64>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// No per-step progress lines on stderr.
    #[arg(short, long)]
    quiet: bool,
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
    /// Render with this integrator instead of the scene's: `path`, `ptracer` (light
    /// tracing), `sppm` (photon mapping), `whitted` (recursive ray tracing) or `radiosity`
    /// (with its defaults), with the scene integrator's max_depth, rr_depth and
    /// hide_emitters.
    #[arg(long, value_name = "NAME")]
    integrator: Option<String>,
    /// Render the scene's sensor number N (from 0, in file order) instead of the first, which
    /// is the one Mitsuba renders.
    #[arg(long, value_name = "N")]
    sensor: Option<usize>,
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
    /// Fail (exit status 1, after writing the image) if any sample was NaN or infinite:
    /// such samples are dropped from the image, and counted in the summary either way.
    #[arg(long)]
    strict: bool,
    /// Render only part I of N of the samples (whole passes, contiguous) and write its sums
    /// to the output as a part file for `penumbra merge` (e.g. one Slurm array task each).
    /// An interrupted part (SIGINT, SIGTERM) writes its samples so far to its checkpoint
    /// (--checkpoint, default the output path with .ckpt appended), which --resume continues.
    #[arg(long, value_name = "I/N", value_parser = parse_part,
          conflicts_with_all = ["time_limit", "target_rel_error", "variance", "preview"])]
    part: Option<(u32, u32)>,
    /// With --part: the parts extend a render of this many spp (a multiple of the pass size)
    /// up to --spp, to be merged with that render's parts.
    #[arg(long, value_name = "SPP", requires = "part", default_value_t = 0)]
    start_spp: u64,
}

#[derive(clap::Args)]
struct MergeArgs {
    /// Part files written by `penumbra render --part I/N`, in any order.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output image (OpenEXR, 32-bit float linear RGB).
    #[arg(short, long, default_value = "out.exr")]
    output: PathBuf,
    /// Merge only the samples up to this spp (a rung of a convergence ladder): parts beyond
    /// it are left out. Default: everything the parts hold.
    #[arg(long)]
    spp: Option<u64>,
    /// Add per-pixel per-sample variance channels (variance.R/G/B) to the EXR.
    #[arg(long)]
    variance: bool,
    /// Also write a tone-mapped sRGB PNG preview.
    #[arg(long, value_name = "PNG")]
    preview: Option<PathBuf>,
    /// Write render statistics (summed over the parts) as JSON.
    #[arg(long, value_name = "JSON")]
    stats: Option<PathBuf>,
    /// No summary line.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_part(s: &str) -> std::result::Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not a part: give I/N with 0 <= I < N (e.g. 0/4)");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n) = (
        i.trim().parse::<u32>().map_err(|_| bad())?,
        n.trim().parse::<u32>().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
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

/// A render stopped by SIGINT or SIGTERM after saving what it had: `main` prints `message`
/// (one line) and exits with status 128 + `signal`, as a shell reports a process killed by
/// that signal (130 for SIGINT, 143 for SIGTERM).
#[derive(Debug)]
struct Interrupted {
    signal: i32,
    message: String,
}

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Interrupted {}

/// SIGINT (Ctrl-C) and SIGTERM (`kill`, Slurm at a job's time limit), caught: each sets
/// `stop`, which the render checks after every pass, and `which` to its number. Further
/// signals do nothing more, so that they cannot interrupt the writes that follow (SIGKILL
/// still ends the process at once; the atomic writes then leave the previous files whole).
struct Signals {
    stop: Arc<AtomicBool>,
    which: Arc<AtomicUsize>,
}

impl Signals {
    fn catch() -> Result<Self> {
        use signal_hook::consts::{SIGINT, SIGTERM};
        let stop = Arc::new(AtomicBool::new(false));
        let which = Arc::new(AtomicUsize::new(0));
        for signal in [SIGINT, SIGTERM] {
            // In this order: `which` is set before `stop` is seen.
            signal_hook::flag::register_usize(signal, which.clone(), signal as usize)
                .and_then(|_| signal_hook::flag::register(signal, stop.clone()))
                .context("cannot install the signal handlers")?;
        }
        Ok(Signals { stop, which })
    }

    /// The signal that stopped the render, if one did: its number and name.
    fn received(&self) -> Option<(i32, &'static str)> {
        if !self.stop.load(Ordering::SeqCst) {
            return None;
        }
        let n = self.which.load(Ordering::SeqCst) as i32;
        Some((
            n,
            match n {
                signal_hook::consts::SIGINT => "SIGINT",
                signal_hook::consts::SIGTERM => "SIGTERM",
                _ => "a signal",
            },
        ))
    }
}

/// Fails unless every one of `outputs` (path, what it is) can be written: its directory
/// exists and takes a new file. Checked before any scene data is loaded, so that a long
/// render never ends in an unwritable path.
fn check_outputs(outputs: &[(&Path, &str)]) -> Result<()> {
    for (path, what) in outputs {
        penumbra::io::atomic::check_writable(path)
            .with_context(|| format!("{}: cannot write {what}", path.display()))?;
    }
    Ok(())
}

/// The checkpoint path of a render: --checkpoint, or the output path with .ckpt appended.
fn checkpoint_path(args: &RenderArgs) -> PathBuf {
    args.checkpoint.clone().unwrap_or_else(|| {
        let mut p = args.output.clone().into_os_string();
        p.push(".ckpt");
        PathBuf::from(p)
    })
}

fn run_render(args: RenderArgs) -> Result<()> {
    let signals = Signals::catch()?;
    let defines = args
        .define
        .iter()
        .map(|d| parse_define(d))
        .collect::<Result<Vec<_>>>()?;
    let checkpointing_asked =
        args.checkpoint_every.is_some() || args.checkpoint.is_some() || args.resume;
    let checkpoint_path = checkpoint_path(&args);
    {
        let mut outputs: Vec<(&Path, &str)> = vec![(
            &args.output,
            if args.part.is_some() {
                "part file"
            } else {
                "image"
            },
        )];
        if checkpointing_asked || args.part.is_some() {
            outputs.push((&checkpoint_path, "checkpoint"));
        }
        if let Some(p) = &args.preview {
            outputs.push((p, "preview"));
        }
        if let Some(p) = &args.stats {
            outputs.push((p, "statistics"));
        }
        check_outputs(&outputs)?;
    }
    let mut desc = Scene::load_description(&args.scene, &defines)?;
    if let Some(n) = args.sensor {
        desc.select_sensor(n)?;
    }
    let scene_hash = progressive::scene_hash(&desc);
    // Mitsuba's integrator `timeout` is the render's time limit unless --time-limit is given
    // (a part's samples are fixed by its plan: it has none).
    let time_limit = match (args.time_limit, desc.timeout) {
        (Some(t), _) => Some(t),
        (None, Some(t)) if args.part.is_none() => Some(Duration::from_secs_f64(t)),
        (None, Some(_)) => {
            eprintln!("warning: the integrator's timeout is ignored by --part (a part renders its planned samples)");
            None
        }
        (None, None) => None,
    };
    if let Some(kind) = &args.integrator {
        desc.use_integrator(kind)?;
    }
    let mut job = Job::build(&desc)?;
    for w in &job.scene.warnings {
        eprintln!("warning: {w}");
    }
    if args.spp == Some(0) {
        bail!("--spp must be at least 1");
    }
    if let Some(t) = args.target_rel_error {
        if !(t > 0.0 && t.is_finite()) {
            bail!("--target-rel-error must be a positive number, got {t}");
        }
    }
    let seed = args.seed.unwrap_or(job.scene.seed);
    let checkpointing = checkpointing_asked.then(|| progressive::Checkpointing {
        path: checkpoint_path.clone(),
        every: args.checkpoint_every.unwrap_or(Duration::from_secs(300)),
    });
    let resume = if args.resume {
        Some(progressive::Checkpoint::read(&checkpoint_path)?)
    } else {
        None
    };
    // The sampler's points per pass: `--spp` sets them as Mitsuba's render(spp=...) does
    // (rounded by the plugin); a resumed render keeps the checkpoint's, so that its further
    // samples continue the same passes (a resumed part has its plan's, which it checks).
    let spp = match (&resume, args.spp) {
        (Some(checkpoint), spp) if args.part.is_none() => {
            job.scene.sampler.sample_count = checkpoint.sampler_points;
            spp.unwrap_or(job.scene.sample_count)
        }
        (_, Some(spp)) => {
            let (rounded, warning) = job.scene.set_sample_count(spp);
            if let Some(w) = warning {
                eprintln!("warning: {w} (--spp)");
            }
            rounded
        }
        (_, None) => job.scene.sample_count,
    };
    let settings = progressive::ProgressiveSettings {
        spp,
        seed,
        threads: args.threads,
        time_limit,
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
        stop: Some(signals.stop.clone()),
    };
    if let penumbra::integrator::Integrator::Aov(aov) = &job.integrator {
        return render_aov(&job.scene, aov, &args, spp, seed);
    }
    if let Some((index, count)) = args.part {
        let plan = progressive::PartPlan {
            index,
            count,
            plan_spp: spp as u64,
            start_spp: args.start_spp,
        };
        let part_settings = progressive::PartSettings {
            seed,
            threads: args.threads,
            scene_hash,
            stop: Some(signals.stop.clone()),
            checkpoint: Some(progressive::Checkpointing {
                path: checkpoint_path.clone(),
                every: args.checkpoint_every.unwrap_or(Duration::MAX),
            }),
        };
        let warned = AtomicBool::new(false);
        let run = progressive::render_part_with(&job, &plan, &part_settings, resume, &|r| {
            warn_checkpoint(r.checkpoint_error.as_deref(), &warned, &|m| {
                eprintln!("{m}")
            })
        })?;
        let part = &run.part;
        let (a, b) = (part.first_sample, part.first_sample + part.samples);
        if let Some((signal, name)) = signals.received() {
            if run.reason == progressive::StopReason::Interrupted {
                let saved = match &run.checkpoint_error {
                    None => format!(
                        "its checkpoint {} holds them (continue with --resume)",
                        checkpoint_path.display()
                    ),
                    Some(e) => format!("its checkpoint was not written: {e}"),
                };
                return Err(Interrupted {
                    signal,
                    message: format!(
                        "interrupted by {name}: part {index}/{count} stopped after samples \
                         {a}..{b}; {saved}; no part file written"
                    ),
                }
                .into());
            }
        }
        progressive::write_checkpoint_retrying(part, &args.output)?;
        // The part file holds everything its checkpoint did.
        if args.resume || args.checkpoint_every.is_some() {
            let _ = std::fs::remove_file(&checkpoint_path);
        }
        if !args.quiet {
            let secs = part.stats.seconds.max(1e-9);
            eprintln!(
                "part {index}/{count} of {spp} spp: samples {a}..{b} of every pixel, {:.2} s, \
                 {:.2} Mpath/s, {} non-finite samples dropped -> {}",
                part.stats.seconds,
                part.stats.paths as f64 / secs / 1e6,
                part.stats.nonfinite,
                args.output.display()
            );
        }
        return strict_check(args.strict, part.stats.nonfinite, &args.output);
    }
    let pixels = (job.scene.width * job.scene.height) as u64;
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
    let warned = AtomicBool::new(false);
    let (progress, reason) = progressive::render_progressive(&job, &settings, resume, &|p| {
        warn_checkpoint(p.checkpoint_error.as_deref(), &warned, &|m| {
            bar.suspend(|| eprintln!("{m}"))
        });
        bar.set_position(p.samples * pixels)
    })?;
    bar.finish_and_clear();
    let interrupted = match signals.received() {
        Some(s) if reason == progressive::StopReason::Interrupted => Some(s),
        _ => None,
    };
    if let (Some((signal, name)), 0) = (interrupted, progress.samples) {
        return Err(Interrupted {
            signal,
            message: format!("interrupted by {name} before the first pass: nothing written"),
        }
        .into());
    }
    write_image(&ImageOutput {
        output: &args.output,
        film: &progress.film,
        spp: progress.samples,
        seed,
        stats: progress.stats,
        reason: reason.as_str(),
        variance: args.variance,
        preview: args.preview.as_deref(),
        stats_json_path: args.stats.as_deref(),
        quiet: args.quiet,
    })?;
    let checkpoint_note = match (&settings.checkpoint, &progress.checkpoint_error) {
        (None, _) => String::new(),
        (Some(cp), None) => format!(
            " and the checkpoint {} (continue with --resume)",
            cp.path.display()
        ),
        (Some(_), Some(e)) => format!("; the checkpoint was not written: {e}"),
    };
    if let Some((signal, name)) = interrupted {
        return Err(Interrupted {
            signal,
            message: format!(
                "interrupted by {name} after {} of {spp} spp: wrote {}{checkpoint_note}",
                progress.samples,
                args.output.display()
            ),
        }
        .into());
    }
    if let Some(e) = &progress.checkpoint_error {
        bail!(
            "the final checkpoint was not written: {e} (the image was written to {})",
            args.output.display()
        );
    }
    strict_check(args.strict, progress.stats.nonfinite, &args.output)
}

/// Prints one warning when a checkpoint write fails (after its retries), and no more until
/// one has succeeded again: the render goes on either way.
fn warn_checkpoint(error: Option<&str>, warned: &AtomicBool, print: &dyn Fn(&str)) {
    match error {
        Some(e) if !warned.swap(true, Ordering::Relaxed) => print(&format!(
            "warning: checkpoint not written, the render goes on (and tries again at the next \
             checkpoint): {e}"
        )),
        Some(_) => {}
        None => warned.store(false, Ordering::Relaxed),
    }
}

/// --strict: an error naming the count if any sample was dropped as NaN or infinite (the
/// image is written by then).
fn strict_check(strict: bool, nonfinite: u64, output: &Path) -> Result<()> {
    if strict && nonfinite > 0 {
        bail!(
            "{nonfinite} non-finite sample{} dropped (--strict); the image was written to {}",
            if nonfinite == 1 { " was" } else { "s were" },
            output.display()
        );
    }
    Ok(())
}

/// An `aov` scene: every channel group rendered with the same samples and written as named
/// channels of one EXR (no progressive features: the run is one render per group).
fn render_aov(
    scene: &Scene,
    aov: &penumbra::integrator::aov::AovIntegrator,
    args: &RenderArgs,
    spp: u32,
    seed: u64,
) -> Result<()> {
    if args.resume
        || args.part.is_some()
        || args.checkpoint.is_some()
        || args.checkpoint_every.is_some()
        || args.time_limit.is_some()
        || args.target_rel_error.is_some()
        || args.variance
        || args.preview.is_some()
    {
        bail!(
            "the aov integrator renders its channels in one run: --resume, --part, \
             --checkpoint, --time-limit, --target-rel-error, --variance and --preview do not \
             apply"
        );
    }
    let (channels, stats) = penumbra::render::render_channels(scene, aov, spp, seed, args.threads)?;
    exr::write_channels(
        &args.output,
        (scene.width, scene.height),
        &channels,
        &render_attributes(spp as u64, seed, stats.seconds),
    )?;
    if !args.quiet {
        let names: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
        eprintln!(
            "{}x{}, {} spp, {:.2} s, channels {}, {} non-finite samples dropped -> {}",
            scene.width,
            scene.height,
            spp,
            stats.seconds,
            names.join(" "),
            stats.nonfinite,
            args.output.display()
        );
    }
    strict_check(args.strict, stats.nonfinite, &args.output)
}

/// The EXR header attributes every render writes: spp, seed, time and penumbra's version.
fn render_attributes(spp: u64, seed: u64, seconds: f64) -> Vec<(&'static str, Attribute)> {
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
struct ImageOutput<'a> {
    output: &'a std::path::Path,
    film: &'a penumbra::film::Film,
    spp: u64,
    seed: u64,
    stats: penumbra::render::RenderStats,
    reason: &'a str,
    variance: bool,
    preview: Option<&'a std::path::Path>,
    stats_json_path: Option<&'a std::path::Path>,
    quiet: bool,
}

fn write_image(o: &ImageOutput) -> Result<()> {
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
        let json = stats_json(&[
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
            ("penumbra_version", format!("\"{}\"", penumbra::VERSION)),
        ]);
        penumbra::io::atomic::write_bytes(path, json.as_bytes())
            .with_context(|| format!("{}: cannot write statistics", path.display()))?;
    }
    if !o.quiet {
        eprintln!(
            "{}x{}, {} spp, {:.2} s, {:.2} Mpath/s, {:.2} Mray/s, mean path length {:.2}, RR ended {:.1}%, \
             {} non-finite samples dropped, stopped: {} -> {}",
            width,
            height,
            spp_done,
            stats.seconds,
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

fn run_merge(args: MergeArgs) -> Result<()> {
    let mut outputs: Vec<(&Path, &str)> = vec![(&args.output, "image")];
    if let Some(p) = &args.preview {
        outputs.push((p, "preview"));
    }
    if let Some(p) = &args.stats {
        outputs.push((p, "statistics"));
    }
    check_outputs(&outputs)?;
    // One part in memory at a time: the merge's memory does not grow with the parts.
    let merged = progressive::merge_part_files(&args.parts, args.spp)?;
    write_image(&ImageOutput {
        output: &args.output,
        film: &merged.film(),
        spp: merged.samples,
        seed: merged.seed,
        stats: merged.stats,
        reason: "merged parts",
        variance: args.variance,
        preview: args.preview.as_deref(),
        stats_json_path: args.stats.as_deref(),
        quiet: args.quiet,
    })
}

fn run_compare(args: CompareArgs) -> Result<()> {
    for (flag, v) in [("--spp-a", args.spp_a), ("--spp-b", args.spp_b)] {
        if let Some(v) = v {
            if !(v > 0.0 && v.is_finite()) {
                bail!("{flag} must be a positive number, got {v}");
            }
        }
    }
    if let Some(r) = args.diff_range {
        if !(r > 0.0 && r.is_finite()) {
            bail!("--diff-range must be a positive number, got {r}");
        }
    }
    let a = exr::read(&args.a)?;
    let b = exr::read(&args.b)?;
    let alpha = penumbra::study::validation::ALPHA;
    let cmp = compare::compare(&a, &b, args.spp_a, args.spp_b, alpha)?;
    let diff_path = args.diff.as_ref().map(|p| p.to_string_lossy().into_owned());
    let mut diff_range = None;
    if let Some(path) = &args.diff {
        let values = compare::signed_difference(&a.rgb, &b.rgb);
        let (range, note) = match args.diff_range {
            Some(r) => (r, "set by --diff-range".to_string()),
            None => (
                compare::default_diff_range(&values),
                "99th percentile of |Δ|".to_string(),
            ),
        };
        let title = format!("A − B: {} − {}", file_name(&args.a), file_name(&args.b));
        penumbra::study::plot::write_diff_png(
            path,
            &penumbra::study::plot::DiffImage {
                width: a.width,
                height: a.height,
                values: &values,
                range,
                range_note: &note,
                title: &title,
            },
        )?;
        diff_range = Some(range);
    }
    let (a_name, b_name) = (args.a.to_string_lossy(), args.b.to_string_lossy());
    if args.json {
        let diff = diff_path
            .as_deref()
            .zip(diff_range)
            .map(|(path, range)| compare::DiffJson { path, range });
        let json = cmp.to_json(&a_name, &b_name, alpha, diff);
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        print!("{}", cmp.text(&a_name, &b_name));
        if let (Some(p), Some(r)) = (&diff_path, diff_range) {
            println!("diff image: {p} (colour range ±{r:.4e})");
        }
    }
    Ok(())
}

fn file_name(p: &std::path::Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

fn run_converge(args: ConvergeArgs) -> Result<()> {
    use penumbra::study::experiment::{self as ex, SeriesResult, Sweep, SweepMode};
    let steps = ex::parse_spp_list(&args.spp).map_err(anyhow::Error::msg)?;
    if args.seeds == 0 {
        bail!("--seeds must be at least 1");
    }
    if let Some(v) = args.reference_spp {
        if !(v > 0.0 && v.is_finite()) {
            bail!("--reference-spp must be a positive number, got {v}");
        }
    }
    let sweep = args
        .sweep
        .as_deref()
        .map(Sweep::parse)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let defines = args
        .define
        .iter()
        .map(|d| parse_define(d))
        .collect::<Result<Vec<_>>>()?;
    let image = exr::read(&args.reference)?;
    let reference = ex::ReferenceImage {
        spp: args.reference_spp.or(image.spp()),
        image,
    };
    let (variants, mode) = ex::scene_variants(&args.scene, &defines, sweep.as_ref())?;
    let first_seed = match args.seed {
        Some(s) => s,
        None => variants[0].description.sensor.sampler.seed,
    };
    let seeds: Vec<u64> = (0..args.seeds as u64)
        .map(|k| first_seed.wrapping_add(k))
        .collect();
    let r = &reference.image;
    for v in &variants {
        let (width, height) = v.description.sensor.film.crop_size;
        if (width as usize, height as usize) != (r.width, r.height) {
            bail!(
                "the scene renders {}x{}, the reference is {}x{} (set the scene's resolution \
                 with -D, e.g. -D res={})",
                width,
                height,
                r.width,
                r.height,
                r.width
            );
        }
    }
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create {}", args.out_dir.display()))?;
    if !args.quiet {
        eprintln!(
            "reference {}: {}x{}, {}, {}",
            args.reference.display(),
            r.width,
            r.height,
            reference
                .spp
                .map_or("spp unknown".into(), |s| format!("{s} spp")),
            match reference.noise_floor() {
                Some(f) => format!("noise floor {f:.3e}"),
                None => "no variance channels: no noise floor, z-test with penumbra's variance \
                         for both terms"
                    .into(),
            }
        );
        if mode == Some(SweepMode::Integrator) {
            if let Some(s) = &sweep {
                eprintln!(
                    "the scene does not use ${0}: --sweep sets the path integrator's {0}",
                    s.name
                );
            }
        }
    }
    let mut results: Vec<SeriesResult> = Vec::new();
    for variant in &variants {
        let job = Job::build(&variant.description)?;
        if results.is_empty() {
            for w in &job.scene.warnings {
                eprintln!("warning: {w}");
            }
        }
        let mut runs = Vec::new();
        for &seed in &seeds {
            let label = if variant.label.is_empty() {
                format!("seed {seed}")
            } else {
                format!("{} seed {seed}", variant.label)
            };
            let quiet = args.quiet;
            let max_seconds = args.max_seconds;
            let run = ex::run_one(
                &job,
                &steps,
                seed,
                args.threads,
                &reference,
                max_seconds,
                &mut |s| {
                    if !quiet {
                        eprintln!(
                            "  {label}: {:>6} spp {:>9.3} s {:>7.3} Mpath/s  RMSE {:.4e}  \
                         relMSE {:.4e}  efficiency {:.4e}{}",
                            s.spp,
                            s.seconds,
                            s.mpaths_per_second,
                            s.metrics.rmse,
                            s.metrics.rel_mse,
                            s.efficiency,
                            s.z_pass_rate
                                .map(|z| format!("  z-test pass {:.3}%", 100.0 * z))
                                .unwrap_or_default()
                        );
                    }
                },
            )?;
            runs.push(run);
        }
        results.push(SeriesResult {
            label: variant.label.clone(),
            value: variant.value.clone(),
            runs,
        });
    }

    let command = std::iter::once("penumbra".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let info = ex::ExperimentInfo {
        scene: args.scene.to_string_lossy().into_owned(),
        reference: args.reference.to_string_lossy().into_owned(),
        reference_spp: reference.spp,
        reference_variance: r.variance.is_some(),
        noise_floor: reference.noise_floor(),
        width: r.width,
        height: r.height,
        defines: defines.iter().cloned().collect(),
        sweep: sweep.as_ref().map(|s| ex::SweepInfo {
            param: s.name.clone(),
            values: s.values.clone(),
            mode: match mode {
                Some(SweepMode::Integrator) => "integrator".into(),
                Some(SweepMode::Sampler) => "sampler".into(),
                _ => "define".into(),
            },
        }),
        seeds: seeds.clone(),
        spp: steps.clone(),
        threads: args.threads,
        penumbra_version: penumbra::VERSION.to_string(),
        command,
    };
    let param = sweep.as_ref().map(|s| s.name.as_str());
    let csv_path = args.out_dir.join("converge.csv");
    let json_path = args.out_dir.join("converge.json");
    let png_path = args.out_dir.join("converge.png");
    std::fs::write(&csv_path, ex::to_csv(param, &results))
        .with_context(|| format!("cannot write {}", csv_path.display()))?;
    std::fs::write(&json_path, ex::to_json(&info, &results)?)
        .with_context(|| format!("cannot write {}", json_path.display()))?;
    let series: Vec<_> = results.iter().map(|r| r.plot_series()).collect();
    let title = format!(
        "{} vs. {}{}{}",
        file_name(&args.scene),
        file_name(&args.reference),
        sweep
            .as_ref()
            .map(|s| format!(", sweep of {}", s.name))
            .unwrap_or_default(),
        if seeds.len() > 1 {
            format!(", {} seeds (mean, min-max)", seeds.len())
        } else {
            String::new()
        }
    );
    penumbra::study::plot::write_series_png(
        &png_path,
        &penumbra::study::plot::SeriesPlot {
            title: &title,
            series: &series,
            floor: reference.noise_floor(),
            y_desc: "RMSE vs. reference",
        },
    )?;

    for res in &results {
        if !res.label.is_empty() {
            println!("\n## {}\n", res.label);
        }
        if seeds.len() > 1 {
            println!(
                "{} seeds ({}..={}); mean over seeds, RMSE as mean ± std [min, max]\n",
                seeds.len(),
                seeds[0],
                seeds[seeds.len() - 1]
            );
        }
        print!("{}", ex::table(res));
    }
    if results.len() > 1 {
        println!(
            "\n| {} | time (s) | RMSE | efficiency | slope |",
            param.unwrap_or("variant")
        );
        println!("|---|---:|---:|---:|---:|");
        for res in &results {
            let last = res.summary().pop();
            let slope = res.slope_spread();
            println!(
                "| {} | {} | {} | {} | {} |",
                res.value.as_deref().unwrap_or(""),
                last.as_ref()
                    .map_or("–".into(), |l| format!("{:.3}", l.seconds.mean)),
                last.as_ref()
                    .map_or("–".into(), |l| format!("{:.4e}", l.rmse.mean)),
                last.as_ref()
                    .map_or("–".into(), |l| format!("{:.4e}", l.efficiency.mean)),
                slope.map_or("n/a".into(), |s| format!("{:.3}", s.mean))
            );
        }
    }
    if !args.quiet {
        eprintln!(
            "wrote {}, {} and {}",
            csv_path.display(),
            json_path.display(),
            png_path.display()
        );
    }
    Ok(())
}

fn run_report(args: ReportArgs) -> Result<()> {
    use penumbra::study::report::{self, ReportImage, ReportPlot, ReportScene};
    let reference = ReportImage::from_file(&args.reference)?;
    let mut images = Vec::with_capacity(args.images.len());
    for path in &args.images {
        images.push(ReportImage::from_file(path)?);
    }
    let mut plots = Vec::new();
    for p in &args.plot {
        let path = if p.is_dir() {
            p.join("converge.png")
        } else {
            p.clone()
        };
        if !path.is_file() {
            bail!(
                "{}: no such plot (give a PNG or a `penumbra converge` output folder)",
                path.display()
            );
        }
        plots.push(ReportPlot {
            caption: path.display().to_string(),
            path,
        });
    }
    let title = args
        .title
        .unwrap_or_else(|| format!("penumbra report: {}", reference.name));
    let scene = ReportScene {
        name: reference.name.clone(),
        reference,
        images,
        plots,
        notes: Vec::new(),
    };
    let summary = report::write_report(&args.output, &title, &[scene])?;
    eprintln!(
        "wrote {} ({:.1} MB): open it in a browser",
        summary.index.display(),
        summary.bytes as f64 / 1e6
    );
    Ok(())
}

fn main() {
    let cli = Cli::parse();
    // PENUMBRA_LIMITS is read once, here, before anything is loaded: a malformed value fails
    // at once with one line (the loaders then use the same value).
    let result = match penumbra::limits::current() {
        Err(e) => Err(e.into()),
        Ok(_) => match cli.command {
            Command::Render(args) => run_render(args),
            Command::Merge(args) => run_merge(args),
            Command::Compare(args) => run_compare(args),
            Command::Converge(args) => run_converge(args),
            Command::Report(args) => run_report(args),
        },
    };
    if let Err(e) = result {
        if let Some(i) = e.downcast_ref::<Interrupted>() {
            eprintln!("{i}");
            std::process::exit(128 + i.signal);
        }
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
