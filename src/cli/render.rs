//! `penumbra render`: its arguments, the progressive render, `--part` and aov renders, and
//! the SIGINT/SIGTERM handling that stops a render with its outputs written.

use super::output::{check_outputs, render_attributes, write_image, ImageOutput};
use super::parse_define;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use penumbra::display::{Frame, LiveView};
use penumbra::io::exr;
use penumbra::progressive;
use penumbra::render::{Engine, Job};
use penumbra::scene::Scene;
use penumbra::simd::Backend;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
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
    /// tracing), `bdpt` (bidirectional path tracing), `sppm` (photon mapping), `whitted`
    /// (recursive ray tracing) or `radiosity` (with its defaults), with the scene
    /// integrator's max_depth, rr_depth and hide_emitters.
    #[arg(long, value_name = "NAME")]
    integrator: Option<String>,
    /// `rgb` (default) renders linear sRGB as Mitsuba's `*_rgb` variants; `spectral` carries
    /// four wavelengths per path and converts them to linear sRGB as Mitsuba's `*_spectral`
    /// variants (`<spectrum>` values kept as spectra, RGB reflectances upsampled; every
    /// integrator but sppm, whitted and radiosity: docs/spectral.md).
    #[arg(long, value_enum, default_value_t = ModeArg::Rgb)]
    mode: ModeArg,
    /// Render the scene's sensor number N (from 0, in file order) instead of the first, which
    /// is the one Mitsuba renders.
    #[arg(long, value_name = "N")]
    sensor: Option<usize>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// The engine that renders camera paths: `scalar` (one path at a time) or `lanes` (16
    /// paths side by side in SIMD lanes, AVX-512 or AVX2 detected at run time; the same
    /// image bit for bit). The lane engine covers the path integrator (and `bdpt` where
    /// its pilot takes no light subpaths); other integrators run on the scalar engine, and
    /// the summary line says which ran. Default scalar: at
    /// this stage the lane engine is slower.
    #[arg(long, value_enum, default_value_t = EngineArg::Scalar)]
    engine: EngineArg,
    /// The lane engine's backend instead of the widest this processor runs: avx512, avx2,
    /// portable or scalar (width 1). For tests and measurements (valgrind cannot run
    /// AVX-512).
    #[arg(long, hide = true, value_name = "NAME")]
    lane_backend: Option<String>,
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
    /// Show the render as it converges in the tev image viewer listening at HOST:PORT
    /// (tev's default: localhost:14158): an image named after the scene and seed, updated
    /// after each pass (at most every --display-every); with --variance a second layer,
    /// rel_error, each pixel's relative standard error. If tev is not there or goes away:
    /// one warning, and the render goes on.
    #[arg(long, value_name = "HOST:PORT", value_parser = parse_display_server,
          conflicts_with = "part")]
    display_server: Option<String>,
    /// With --display-server: the least time between two images sent (e.g. 0.5s, 10s).
    #[arg(long, value_name = "DURATION", value_parser = parse_duration,
          requires = "display_server")]
    display_every: Option<Duration>,
    /// With --part: the parts extend a render of this many spp (a multiple of the pass size)
    /// up to --spp, to be merged with that render's parts.
    #[arg(long, value_name = "SPP", requires = "part", default_value_t = 0)]
    start_spp: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ModeArg {
    Rgb,
    Spectral,
}

impl From<ModeArg> for penumbra::spectrum::Mode {
    fn from(m: ModeArg) -> Self {
        match m {
            ModeArg::Rgb => penumbra::spectrum::Mode::Rgb,
            ModeArg::Spectral => penumbra::spectrum::Mode::Spectral,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum EngineArg {
    Scalar,
    Lanes,
}

/// The engine of `--engine` and `--lane-backend`.
fn engine(args: &RenderArgs) -> Result<Engine> {
    let backend = match &args.lane_backend {
        None => None,
        Some(name) => Some(Backend::from_name(name).with_context(|| {
            format!("unknown lane backend '{name}' (avx512, avx2, portable or scalar)")
        })?),
    };
    Ok(match (args.engine, backend) {
        (EngineArg::Scalar, None) => Engine::Scalar,
        (EngineArg::Scalar, Some(_)) => bail!("--lane-backend needs --engine lanes"),
        (EngineArg::Lanes, b) => Engine::Lanes(b),
    })
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

pub(super) fn parse_display_server(s: &str) -> std::result::Result<String, String> {
    penumbra::display::parse_address(s)
}

pub(super) fn parse_duration(s: &str) -> std::result::Result<Duration, String> {
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

/// A render stopped by SIGINT or SIGTERM after saving what it had: `main` prints `message`
/// (one line) and exits with status 128 + `signal`, as a shell reports a process killed by
/// that signal (130 for SIGINT, 143 for SIGTERM).
#[derive(Debug)]
pub(crate) struct Interrupted {
    pub(crate) signal: i32,
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

/// The checkpoint path of a render: --checkpoint, or the output path with .ckpt appended.
fn checkpoint_path(args: &RenderArgs) -> PathBuf {
    args.checkpoint.clone().unwrap_or_else(|| {
        let mut p = args.output.clone().into_os_string();
        p.push(".ckpt");
        PathBuf::from(p)
    })
}

pub(crate) fn run_render(args: RenderArgs) -> Result<()> {
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
    // (the mode is part of the scene's identity: checkpoints and parts of one mode do not
    // resume or merge with the other's)
    desc.mode = args.mode.into();
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
    job.engine = engine(&args)?;
    // (fails here, before any work, if a named lane backend cannot run)
    let engine_ran = job.engine.resolve(&job.integrator)?;
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
        return render_aov(&job.scene, aov, &args, spp, seed, engine_ran);
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
                 engine {}{}, {:.2} Mpath/s, {} non-finite samples dropped -> {}",
                part.stats.seconds,
                engine_ran,
                super::output::lane_summary(&part.stats.lanes),
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
    let live = match &args.display_server {
        None => None,
        Some(address) => Some(live_view(&args, address, &job, seed, &bar)?),
    };
    let warned = AtomicBool::new(false);
    let (progress, reason) = progressive::render_progressive(&job, &settings, resume, &|p| {
        warn_checkpoint(p.checkpoint_error.as_deref(), &warned, &|m| {
            bar.suspend(|| eprintln!("{m}"))
        });
        bar.set_position(p.samples * pixels);
        if let Some(live) = &live {
            live.offer(&p.film);
        }
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
    // The final image, once the EXR is written: the last image tev shows is the EXR's.
    if let Some(live) = live {
        live.finish(&progress.film);
    }
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

/// A render's live view in tev (`--display-server`): its image name and layers, and the
/// sender.
struct Live {
    view: LiveView,
    name: String,
    rel_error: bool,
}

impl Live {
    /// After a pass: the film as a new image, if one is due.
    fn offer(&self, film: &penumbra::film::Film) {
        if self.view.due() {
            self.view
                .send(Frame::from_film(&self.name, film, self.rel_error));
        }
    }

    /// The final film, written before this returns (or given up on, with a warning).
    fn finish(self, film: &penumbra::film::Film) {
        let last = Frame::from_film(&self.name, film, self.rel_error);
        self.view.finish(Some(last));
    }
}

/// Starts the live view of `--display-server`: the image is named after the scene file and
/// the seed (so that renders of several scenes or seeds sit side by side in tev), with the
/// relative error layer under --variance (not for sppm, which has no per-pixel variance).
/// Its warnings go around the progress bar.
fn live_view(
    args: &RenderArgs,
    address: &str,
    job: &Job,
    seed: u64,
    bar: &ProgressBar,
) -> Result<Live> {
    let bar = bar.clone();
    let warn: penumbra::display::Warn = Arc::new(move |m: &str| bar.suspend(|| eprintln!("{m}")));
    let sppm = matches!(job.integrator, penumbra::integrator::Integrator::Sppm(_));
    if args.variance && sppm {
        warn("warning: sppm has no per-pixel variance: the live view shows R, G, B only");
    }
    let stem = args
        .scene
        .file_stem()
        .map_or_else(|| "penumbra".into(), |s| s.to_string_lossy().into_owned());
    Ok(Live {
        view: LiveView::start(
            address,
            args.display_every
                .unwrap_or(penumbra::display::DEFAULT_INTERVAL),
            warn,
        )?,
        name: format!("{stem} seed {seed}"),
        rel_error: args.variance && !sppm,
    })
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
    engine: penumbra::render::EngineRan,
) -> Result<()> {
    if args.resume
        || args.part.is_some()
        || args.checkpoint.is_some()
        || args.checkpoint_every.is_some()
        || args.time_limit.is_some()
        || args.target_rel_error.is_some()
        || args.variance
        || args.preview.is_some()
        || args.display_server.is_some()
    {
        bail!(
            "the aov integrator renders its channels in one run: --resume, --part, \
             --checkpoint, --time-limit, --target-rel-error, --variance, --preview and \
             --display-server do not apply"
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
            "{}x{}, {} spp, {:.2} s, engine {}, channels {}, {} non-finite samples dropped -> {}",
            scene.width,
            scene.height,
            spp,
            stats.seconds,
            engine,
            names.join(" "),
            stats.nonfinite,
            args.output.display()
        );
    }
    strict_check(args.strict, stats.nonfinite, &args.output)
}
