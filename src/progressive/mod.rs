//! Long renders: samples are drawn in passes of a fixed size, each continuing the previous
//! one's sample indices, so that a render can stop on a time limit or a target error, write
//! checkpoints of its running sums, and be resumed, or be split into parts rendered
//! anywhere (`--part i/N`, e.g. a Slurm job array) and merged.
//!
//! The pass schedule depends only on the image size: pass k holds the samples
//! [k·p, (k+1)·p) of every pixel, p = [`pass_spp`]. Each pass film is summed in a fixed order
//! (tiles, then pixels), and passes are added exactly ([`ExactFilm`]: exact, canonical sums
//! at any scale, so the grouping of passes does not matter). Hence a render resumed from a
//! checkpoint, and the merge of any split into parts along pass boundaries, are bit-identical
//! to the same render made in one go, in the image and in the checkpoint's bytes.
//!
//! The render loop is here; `checkpoint` holds checkpoints (the file format, writing with
//! retries, reading and resuming) and the scene identity they store; `parts` holds split
//! renders (`render --part`, part plans and the merge of part files).

mod checkpoint;
mod parts;

pub use checkpoint::{
    fnv1a, scene_hash, write_checkpoint_retrying, Checkpoint, CheckpointHeader,
    CHECKPOINT_RETRY_DELAYS,
};
pub use parts::{
    merge_part_files, merge_parts, part_range, render_part, render_part_with, PartPlan, PartRun,
    PartSettings,
};

use crate::error::{Error, Result};
use crate::film::{ExactFilm, Film};
use crate::render::{render_with, Job, RenderSettings, RenderStats};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Samples per pixel per pass: about 2^18 paths per pass (a fraction of a second), at least 1.
pub fn pass_spp(width: usize, height: usize) -> u32 {
    ((1usize << 18) / (width * height).max(1)).clamp(1, 256) as u32
}

/// What the relative standard error target refers to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ErrorTarget {
    /// The relative standard error of the image mean (worst channel).
    ImageMean,
    /// The mean over pixels of each pixel's relative standard error (of its luminance;
    /// pixels with zero mean are left out).
    PerPixel,
}

#[derive(Clone, Debug)]
pub struct Checkpointing {
    pub path: PathBuf,
    pub every: Duration,
}

#[derive(Clone, Debug)]
pub struct ProgressiveSettings {
    /// Target samples per pixel.
    pub spp: u32,
    pub seed: u64,
    pub threads: Option<usize>,
    pub time_limit: Option<Duration>,
    /// Stop once the estimated relative standard error is at most this.
    pub target_rel_error: Option<(f64, ErrorTarget)>,
    pub checkpoint: Option<Checkpointing>,
    /// Identifies the scene (see [`scene_hash`]); stored in checkpoints.
    pub scene_hash: u64,
    /// Set from another thread to stop the render after the pass under way (e.g. on Ctrl-C
    /// in the Python module): the render ends with [`StopReason::Interrupted`] and the
    /// samples of the passes finished so far (and a final checkpoint, if checkpointing).
    pub stop: Option<Arc<AtomicBool>>,
}

/// Why a progressive render stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    SppReached,
    TimeLimit,
    TargetError,
    /// [`ProgressiveSettings::stop`] was set.
    Interrupted,
}

impl StopReason {
    /// As the EXR header's `stop_reason` and the summary line say it.
    pub fn as_str(self) -> &'static str {
        match self {
            StopReason::SppReached => "spp reached",
            StopReason::TimeLimit => "time limit",
            StopReason::TargetError => "target error reached",
            StopReason::Interrupted => "interrupted",
        }
    }
}

/// The running state of a render: sums and counters.
#[derive(Clone, Debug)]
pub struct Progress {
    /// The sums so far (as f64, from `exact`).
    pub film: Film,
    /// The exact sums the passes are added to.
    pub exact: ExactFilm,
    /// Samples per pixel drawn so far (an SPPM render's iterations).
    pub samples: u64,
    pub stats: RenderStats,
    /// An SPPM render's state (its film is made from it, not summed).
    pub sppm: Option<crate::integrator::sppm::SppmState>,
    /// Checkpoint writes that failed so far (each after its retries, see
    /// [`write_checkpoint_retrying`]): a failed checkpoint never stops the render.
    pub checkpoint_failures: u64,
    /// Why the latest checkpoint write failed; `None` once a later one succeeds. Set when
    /// [`render_progressive`] returns, it is the final checkpoint's failure: the file on disk
    /// (if any) holds an earlier state.
    pub checkpoint_error: Option<String>,
}

/// Minimum samples per pixel before a target error is trusted (variance estimates from fewer
/// samples are too noisy to stop on).
pub const MIN_SPP_FOR_TARGET: u64 = 16;

/// Estimated relative standard error of the current estimate. Computed in f64 from the
/// film's f64 means and variances, so that it does not depend on the scene's scale: a scene
/// whose radiance is scaled by a power of two gives the same error, bit for bit (variances
/// of a dim scene underflow f32: 2⁻⁶⁶ radiance makes them ~2⁻¹³²).
pub fn relative_standard_error(film: &Film, target: ErrorTarget) -> f64 {
    let pixels = film.width * film.height;
    let spp = film.spp();
    match target {
        ErrorTarget::ImageMean => {
            let n = pixels as f64;
            let (mut m, mut v) = ([0.0f64; 3], [0.0f64; 3]);
            for i in 0..pixels {
                let mean = film.mean_f64(i);
                let var = film.sample_variance_f64(i, spp);
                let w = film.weight[i];
                for c in 0..3 {
                    m[c] += mean[c];
                    if w > 0.0 {
                        v[c] += var[c] / w;
                    }
                }
            }
            let mut worst: f64 = 0.0;
            for c in 0..3 {
                let mc = m[c] / n;
                if mc > 0.0 {
                    worst = worst.max(v[c].sqrt() / n / mc);
                }
            }
            worst
        }
        ErrorTarget::PerPixel => {
            let lum = |p: &[f64; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
            let (mut acc, mut count) = (0.0, 0usize);
            for i in 0..pixels {
                let (m, v, w) = (
                    film.mean_f64(i),
                    film.sample_variance_f64(i, spp),
                    film.weight[i],
                );
                let lm = lum(&m);
                if lm > 0.0 && w > 0.0 {
                    acc += (lum(&v) / w).sqrt() / lm;
                    count += 1;
                }
            }
            if count == 0 {
                0.0
            } else {
                acc / count as f64
            }
        }
    }
}

/// Renders progressively from `resume` (or from scratch) until the target spp, the time limit
/// or the target error is reached. `on_pass` sees the state after every pass.
pub fn render_progressive(
    job: &Job,
    settings: &ProgressiveSettings,
    resume: Option<Checkpoint>,
    on_pass: &(dyn Fn(&Progress) + Sync),
) -> Result<(Progress, StopReason)> {
    let scene = &job.scene;
    if matches!(job.integrator, crate::integrator::Integrator::Aov(_)) {
        return Err(Error::Invalid(
            "the aov integrator writes named channels, not an RGB image: render it with \
             `penumbra render` (or render::render_channels)"
                .into(),
        ));
    }
    // SPPM's iterations depend on each other (radii, photon counts): its passes continue a
    // state, which checkpoints save, instead of adding films.
    let sppm = match &job.integrator {
        crate::integrator::Integrator::Sppm(s) => Some(s),
        _ => None,
    };
    if sppm.is_some() && settings.target_rel_error.is_some() {
        return Err(Error::Invalid(
            "an sppm render has no per-pixel variance to estimate its error from: use --spp \
             or --time-limit instead of a target error"
                .into(),
        ));
    }
    let pass = pass_spp(scene.width, scene.height);
    let mut progress = match resume {
        Some(c) => {
            c.check_matches(scene, settings, pass)?;
            let film = match (sppm, &c.sppm) {
                (Some(_), Some(state)) => state.film(scene),
                (None, None) => c.exact.to_film(scene.filter),
                (Some(_), None) => {
                    return Err(Error::Invalid(
                        "cannot resume: the checkpoint holds a render of another integrator, \
                         not sppm"
                            .into(),
                    ))
                }
                (None, Some(_)) => {
                    return Err(Error::Invalid(
                        "cannot resume: the checkpoint holds an sppm render".into(),
                    ))
                }
            };
            Progress {
                film,
                exact: c.exact,
                samples: c.samples,
                stats: c.stats,
                sppm: c.sppm,
                checkpoint_failures: 0,
                checkpoint_error: None,
            }
        }
        None => Progress {
            film: Film::new(scene.width, scene.height, scene.filter),
            exact: ExactFilm::new(scene.width, scene.height),
            samples: 0,
            stats: RenderStats::default(),
            sppm: sppm.map(|s| crate::integrator::sppm::SppmState::new(scene, s)),
            checkpoint_failures: 0,
            checkpoint_error: None,
        },
    };
    // The samples the checkpoint file holds (as far as this render knows): the final
    // checkpoint is not written again when the last pass's is already on disk.
    let mut checkpointed = progress.samples;
    // SPPM's passes run on one pool (a path render's passes make theirs in `render`); the
    // exact film adds its passes on one too, with the render's thread count.
    let pool = crate::render::thread_pool(settings.threads)?;
    let sppm_pool = sppm.map(|_| &pool);
    // (bdpt's pilot, once for all passes: its choice depends on the seed only.)
    let integrator = job
        .integrator
        .resolved(scene, settings.seed, settings.spp as u64, &pool);
    let start = Instant::now();
    let mut last_checkpoint = Instant::now();
    let reason = loop {
        if progress.samples >= settings.spp as u64 {
            break StopReason::SppReached;
        }
        if settings
            .stop
            .as_ref()
            .is_some_and(|s| s.load(Ordering::Relaxed))
        {
            break StopReason::Interrupted;
        }
        // (A time limit still lets the first pass render: an image of 0 samples is no image.)
        if let Some(limit) = settings.time_limit {
            if progress.samples > 0 && start.elapsed() >= limit {
                break StopReason::TimeLimit;
            }
        }
        if let Some((target, kind)) = settings.target_rel_error {
            if progress.samples >= MIN_SPP_FOR_TARGET
                && relative_standard_error(&progress.film, kind) <= target
            {
                break StopReason::TargetError;
            }
        }
        let spp = (pass as u64).min(settings.spp as u64 - progress.samples) as u32;
        let pass_settings = RenderSettings {
            spp,
            seed: settings.seed,
            threads: settings.threads,
            sampler: None,
            first_sample: progress.samples,
        };
        let stats = match (sppm, progress.sppm.as_mut(), sppm_pool) {
            (Some(integrator), Some(state), Some(pool)) => {
                let stats =
                    integrator.iterate(scene, &pass_settings, pool, state, spp as u64, &|_, _| {});
                progress.film = state.film(scene);
                stats
            }
            _ => {
                let out = render_with(scene, &integrator, job.engine, &pass_settings, &|_, _| {})?;
                let exact = &mut progress.exact;
                pool.install(|| exact.add(&out.film))
                    .map_err(|e| Error::Invalid(e.to_string()))?;
                progress.film = pool.install(|| progress.exact.to_film(scene.filter));
                out.stats
            }
        };
        progress.samples += spp as u64;
        progress.stats.paths += stats.paths;
        progress.stats.path += stats.path;
        progress.stats.lanes += stats.lanes;
        progress.stats.engine = stats.engine;
        progress.stats.light_paths = stats.light_paths;
        progress.stats.nonfinite += stats.nonfinite;
        progress.stats.seconds += stats.seconds;
        if let Some(cp) = &settings.checkpoint {
            if last_checkpoint.elapsed() >= cp.every {
                let c = Checkpoint::from_progress(&progress, settings, pass, scene);
                note_checkpoint(&mut progress, write_checkpoint_retrying(&c, &cp.path));
                if progress.checkpoint_error.is_none() {
                    checkpointed = progress.samples;
                }
                last_checkpoint = Instant::now();
            }
        }
        on_pass(&progress);
    };
    // The final checkpoint (unless the file holds this state already): a failure is
    // reported in `progress.checkpoint_error`, so that the caller still writes its image.
    if let Some(cp) = &settings.checkpoint {
        if checkpointed != progress.samples || progress.checkpoint_error.is_some() {
            let c = Checkpoint::from_progress(&progress, settings, pass, scene);
            note_checkpoint(&mut progress, write_checkpoint_retrying(&c, &cp.path));
        }
    }
    Ok((progress, reason))
}

/// Records the outcome of a checkpoint write in `progress`.
fn note_checkpoint(progress: &mut Progress, r: Result<()>) {
    match r {
        Ok(()) => progress.checkpoint_error = None,
        Err(e) => {
            progress.checkpoint_failures += 1;
            progress.checkpoint_error = Some(e.to_string());
        }
    }
}
