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

use crate::error::{Error, Result};
use crate::film::{ExactFilm, Film, Filter, EXACT_VALUES};
use crate::render::{render, Job, RenderSettings, RenderStats};
use crate::scene::Scene;
use std::io::Read;
use std::path::{Path, PathBuf};
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
                let out = render(scene, &job.integrator, &pass_settings, &|_, _| {})?;
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

/// Waits before the second, third, ... attempt of a checkpoint write.
pub const CHECKPOINT_RETRY_DELAYS: [Duration; 2] =
    [Duration::from_millis(100), Duration::from_millis(400)];

/// Writes a checkpoint (or part file), trying again after each of
/// [`CHECKPOINT_RETRY_DELAYS`] when a write fails (a full disk that is cleared, a file
/// system that hiccups); the last failure is returned with the number of attempts.
pub fn write_checkpoint_retrying(c: &Checkpoint, path: &Path) -> Result<()> {
    let mut attempt = 0;
    loop {
        match c.write(path) {
            Ok(()) => return Ok(()),
            Err(e) => match CHECKPOINT_RETRY_DELAYS.get(attempt) {
                Some(delay) => std::thread::sleep(*delay),
                None => {
                    return Err(Error::Invalid(format!(
                        "{e} ({} attempts)",
                        CHECKPOINT_RETRY_DELAYS.len() + 1
                    )))
                }
            },
        }
        attempt += 1;
    }
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

/// FNV-1a, 64 bit: a stable hash for scene identity (not for security).
pub fn fnv1a(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

/// Identity of a scene for checkpoints: its typed description (every parameter, after
/// defaults and -D overrides) and the bytes of every file it loads (meshes, grids, images),
/// each read up to the largest file any loader reads under the limits in effect
/// ([`crate::limits::Limits::input_file_bytes`]; the defaults' if `PENUMBRA_LIMITS` is
/// malformed, which the loaders refuse).
pub fn scene_hash(desc: &crate::scene::description::SceneDescription) -> u64 {
    let bound = crate::limits::current()
        .unwrap_or_default()
        .input_file_bytes();
    let mut h = fnv1a(format!("{desc:?}").as_bytes(), 0xcbf2_9ce4_8422_2325);
    for path in desc.files() {
        // Streamed, and bounded as the loaders are: a device, a FIFO, a directory or a file
        // larger than any loader reads is left out here (its loader then refuses it).
        let mut file_h = h;
        let read = crate::io::read_file_chunks(path, bound, |chunk| file_h = fnv1a(chunk, file_h));
        if read.is_ok() {
            h = file_h;
        }
    }
    h
}

/// A render's running sums on disk.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    pub version: String,
    pub scene_hash: u64,
    pub seed: u64,
    pub pass_spp: u32,
    /// The sampler's points per pass ([`crate::sampler::Sampler::sample_count`]): a resumed
    /// render continues with the same passes.
    pub sampler_points: u32,
    /// The samples per pixel this file holds: [first_sample, first_sample + samples).
    pub first_sample: u64,
    pub samples: u64,
    /// The render's target spp (a part's plan; a checkpoint's `--spp`).
    pub plan_spp: u64,
    /// Where the part's plan starts (`--start-spp`; 0 for a checkpoint).
    pub plan_start: u64,
    /// For a part file: (i, N) of `--part i/N`; None for a checkpoint.
    pub part: Option<(u32, u32)>,
    pub stats: RenderStats,
    pub filter: Filter,
    pub exact: ExactFilm,
    /// An SPPM render's state (its `exact` film is then empty).
    pub sppm: Option<crate::integrator::sppm::SppmState>,
}

/// What a checkpoint or part file says about itself, without its sums: enough to plan a
/// merge before any film is read.
#[derive(Clone, Debug)]
pub struct CheckpointHeader {
    pub version: String,
    pub scene_hash: u64,
    pub seed: u64,
    pub pass_spp: u32,
    pub sampler_points: u32,
    pub first_sample: u64,
    pub samples: u64,
    pub plan_spp: u64,
    pub plan_start: u64,
    pub part: Option<(u32, u32)>,
    pub stats: RenderStats,
    pub filter: Filter,
    pub width: usize,
    pub height: usize,
    /// The film's sample count.
    pub film_samples: u64,
}

impl PartialEq for CheckpointHeader {
    fn eq(&self, o: &Self) -> bool {
        let stats = |s: &RenderStats| {
            (
                s.paths,
                s.path.rays,
                s.path.bounces,
                s.path.rr_terminated,
                s.nonfinite,
                s.seconds.to_bits(),
            )
        };
        self.version == o.version
            && (
                self.scene_hash,
                self.seed,
                self.pass_spp,
                self.sampler_points,
            ) == (o.scene_hash, o.seed, o.pass_spp, o.sampler_points)
            && (
                self.first_sample,
                self.samples,
                self.plan_spp,
                self.plan_start,
            ) == (o.first_sample, o.samples, o.plan_spp, o.plan_start)
            && self.part == o.part
            && stats(&self.stats) == stats(&o.stats)
            && self.filter == o.filter
            && (self.width, self.height, self.film_samples) == (o.width, o.height, o.film_samples)
    }
}

/// Today's format: the header, then the exact film's canonical state
/// ([`ExactFilm::write_state`]: 270 B per pixel plus spilled values), then the SPPM section.
const MAGIC: &[u8; 8] = b"PNBRCKP5";
/// The format before exact-at-any-scale films (issue 40): the same header, then every sum as
/// an i128 count of 2⁻⁴⁸ (240 B per pixel). Read (converted exactly: a count q is q · 2⁻⁴⁸),
/// never written.
const MAGIC_V4: &[u8; 8] = b"PNBRCKP4";

/// An SPPM pixel in a checkpoint: L_d (3), N, τ (3), radius, as f64.
const SPPM_PIXEL_BYTES: usize = 64;

/// The longest version string a checkpoint may hold (a longer one is corrupt).
const MAX_VERSION_BYTES: usize = 256;

/// Header bytes after the magic, besides the version string: u32 version length, 9 u64, 5
/// u32, an f64, 5 u64 and an f64.
const HEADER_FIXED_BYTES: usize = 4 + 9 * 8 + 5 * 4 + 8 + 5 * 8 + 8;

/// Where a file's bytes are: for its error messages.
fn corrupt(path: &Path, m: &str) -> Error {
    Error::Invalid(format!(
        "{}: not a valid penumbra checkpoint or part file ({m})",
        path.display()
    ))
}

/// Parses the header after the magic; returns it and the position after it.
fn parse_header(bytes: &[u8], path: &Path) -> Result<(CheckpointHeader, usize)> {
    let bad = |m: &str| corrupt(path, m);
    let mut r = Reader { b: bytes, pos: 8 };
    let vlen = r.u32().ok_or_else(|| bad("truncated"))? as usize;
    if vlen > MAX_VERSION_BYTES {
        return Err(bad("bad version"));
    }
    let version = String::from_utf8(r.take(vlen).ok_or_else(|| bad("truncated"))?.to_vec())
        .map_err(|_| bad("bad version"))?;
    let mut u = || r.u64().ok_or_else(|| bad("truncated"));
    let (scene_hash, seed, first_sample, samples, plan_spp) = (u()?, u()?, u()?, u()?, u()?);
    let plan_start = u()?;
    let (width, height, film_samples) = (u()?, u()?, u()?);
    let pixels = width.checked_mul(height).ok_or_else(|| bad("resolution"))?;
    let limits = crate::limits::current()?;
    if pixels > limits.render_pixels {
        return Err(Error::Invalid(format!(
            "{}: the checkpoint or part file's resolution of {width}x{height} pixels exceeds {}",
            path.display(),
            limits.exceeded(crate::limits::Limit::RenderPixels)
        )));
    }
    let mut u = || r.u32().ok_or_else(|| bad("truncated"));
    let (pass_spp, sampler_points, part_i, part_n, filter_kind) = (u()?, u()?, u()?, u()?, u()?);
    let filter_param = r.f64().ok_or_else(|| bad("truncated"))?;
    let filter = match filter_kind {
        0 => Filter::Box,
        1 => Filter::Tent {
            radius: filter_param,
        },
        2 => Filter::Gaussian {
            stddev: filter_param,
        },
        _ => return Err(bad("unknown filter")),
    };
    let mut u = || r.u64().ok_or_else(|| bad("truncated"));
    let (paths, rays, bounces, rr, nonfinite) = (u()?, u()?, u()?, u()?, u()?);
    let seconds = r.f64().ok_or_else(|| bad("truncated"))?;
    if pass_spp == 0 || sampler_points == 0 {
        return Err(bad("zero pass size"));
    }
    if first_sample.checked_add(samples).is_none() || plan_start > plan_spp {
        return Err(bad("sample range"));
    }
    let part = (part_n > 0).then_some((part_i, part_n));
    if part.is_some_and(|(i, n)| i >= n) {
        return Err(bad("part index out of range"));
    }
    let header = CheckpointHeader {
        version,
        scene_hash,
        seed,
        pass_spp,
        sampler_points,
        first_sample,
        samples,
        plan_spp,
        plan_start,
        part,
        stats: RenderStats {
            paths,
            path: crate::integrator::PathStats {
                rays,
                bounces,
                rr_terminated: rr,
            },
            nonfinite,
            seconds,
        },
        filter,
        width: width as usize,
        height: height as usize,
        film_samples,
    };
    Ok((header, r.pos))
}

impl Checkpoint {
    fn from_progress(p: &Progress, s: &ProgressiveSettings, pass_spp: u32, scene: &Scene) -> Self {
        Checkpoint {
            version: crate::VERSION.to_string(),
            scene_hash: s.scene_hash,
            seed: s.seed,
            pass_spp,
            sampler_points: scene.sampler.sample_count,
            first_sample: 0,
            samples: p.samples,
            plan_spp: s.spp as u64,
            plan_start: 0,
            part: None,
            stats: p.stats,
            filter: scene.filter,
            exact: p.exact.clone(),
            sppm: p.sppm.clone(),
        }
    }

    /// Everything but the sums.
    pub fn header(&self) -> CheckpointHeader {
        CheckpointHeader {
            version: self.version.clone(),
            scene_hash: self.scene_hash,
            seed: self.seed,
            pass_spp: self.pass_spp,
            sampler_points: self.sampler_points,
            first_sample: self.first_sample,
            samples: self.samples,
            plan_spp: self.plan_spp,
            plan_start: self.plan_start,
            part: self.part,
            stats: self.stats,
            filter: self.filter,
            width: self.exact.width,
            height: self.exact.height,
            film_samples: self.exact.samples,
        }
    }

    fn check_matches(&self, scene: &Scene, s: &ProgressiveSettings, pass_spp: u32) -> Result<()> {
        let refuse = |what: String| {
            Err(Error::Invalid(format!(
                "cannot resume: the checkpoint was made {what}"
            )))
        };
        if self.part.is_some() || self.first_sample != 0 {
            return refuse("by `render --part`: merge parts with `penumbra merge`".into());
        }
        if self.version != crate::VERSION {
            return refuse(format!(
                "by penumbra {} (this is {})",
                self.version,
                crate::VERSION
            ));
        }
        if self.scene_hash != s.scene_hash {
            return refuse("from another scene (or other -D values or mesh files)".into());
        }
        if self.seed != s.seed {
            return refuse(format!(
                "with seed {} (this render uses {})",
                self.seed, s.seed
            ));
        }
        if (self.exact.width, self.exact.height) != (scene.width, scene.height)
            || self.pass_spp != pass_spp
            || self.filter != scene.filter
        {
            return refuse("for another resolution".into());
        }
        if self.sampler_points != scene.sampler.sample_count {
            return refuse(format!(
                "with {} sampler points per pass (this render uses {})",
                self.sampler_points, scene.sampler.sample_count
            ));
        }
        Ok(())
    }

    /// The file's bytes (see [`Checkpoint::write`]): a function of the header and the exact
    /// sums alone, so that two groupings of the same passes give the same bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut buf = Vec::with_capacity(
            256 + self.exact.width * self.exact.height * (18 * EXACT_VALUES + SPPM_PIXEL_BYTES),
        );
        buf.extend_from_slice(MAGIC);
        let v = self.version.as_bytes();
        buf.extend_from_slice(&(v.len() as u32).to_le_bytes());
        buf.extend_from_slice(v);
        let (part_i, part_n) = self.part.unwrap_or((0, 0));
        let (filter_kind, filter_param) = match self.filter {
            Filter::Box => (0u32, 0.0f64),
            Filter::Tent { radius } => (1, radius),
            Filter::Gaussian { stddev } => (2, stddev),
        };
        for x in [
            self.scene_hash,
            self.seed,
            self.first_sample,
            self.samples,
            self.plan_spp,
            self.plan_start,
            self.exact.width as u64,
            self.exact.height as u64,
            self.exact.samples,
        ] {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        for x in [
            self.pass_spp,
            self.sampler_points,
            part_i,
            part_n,
            filter_kind,
        ] {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        buf.extend_from_slice(&filter_param.to_le_bytes());
        let st = &self.stats;
        for x in [
            st.paths,
            st.path.rays,
            st.path.bounces,
            st.path.rr_terminated,
            st.nonfinite,
        ] {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        buf.extend_from_slice(&st.seconds.to_le_bytes());
        self.exact.write_state(&mut buf);
        match &self.sppm {
            None => buf.push(0),
            Some(st) => {
                buf.push(1);
                buf.extend_from_slice(&st.iterations.to_le_bytes());
                buf.extend_from_slice(&st.photons_emitted.to_le_bytes());
                for i in 0..st.ld.len() {
                    let (ld, tau) = (st.ld[i], st.tau[i]);
                    for v in [
                        ld.x,
                        ld.y,
                        ld.z,
                        st.big_n[i],
                        tau.x,
                        tau.y,
                        tau.z,
                        st.radius[i],
                    ] {
                        buf.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
        let checksum = fnv1a(&buf, 0xcbf2_9ce4_8422_2325);
        buf.extend_from_slice(&checksum.to_le_bytes());
        buf
    }

    /// Writes atomically ([`crate::io::atomic`]): to a temporary file of a unique name next
    /// to `path`, synced, then renamed over it, so that a crash never leaves a half-written
    /// checkpoint and two processes writing the same path never mix their bytes.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::atomic::write_bytes(path, &self.to_bytes()).map_err(|cause| Error::Io {
            path: path.to_path_buf(),
            cause,
        })
    }

    /// Reads a checkpoint or part file written by [`Checkpoint::write`] (or by the previous
    /// format, `PNBRCKP4`, converted exactly).
    pub fn read(path: &Path) -> Result<Self> {
        let bytes =
            crate::io::read_file_limited(path, checkpoint_file_limit()?).map_err(|cause| {
                Error::Io {
                    path: path.to_path_buf(),
                    cause,
                }
            })?;
        Self::parse(&bytes, path)
    }

    /// Reads only a file's header (a bounded prefix of it), checking that the file is as long
    /// as its resolution needs: for planning a merge before reading any film. The rest, and
    /// the checksum, are checked when the whole file is read.
    pub fn read_header(path: &Path) -> Result<CheckpointHeader> {
        let io = |cause| Error::Io {
            path: path.to_path_buf(),
            cause,
        };
        let (f, len) = crate::io::open_regular(path, checkpoint_file_limit()?).map_err(io)?;
        let mut prefix = Vec::new();
        f.take((8 + HEADER_FIXED_BYTES + MAX_VERSION_BYTES) as u64)
            .read_to_end(&mut prefix)
            .map_err(io)?;
        let (magic, h, pos) = Self::parse_magic_and_header(&prefix, path)?;
        let film =
            (h.width * h.height) as u64 * if magic == 4 { 16 } else { 18 } * EXACT_VALUES as u64;
        if len < pos as u64 + film + 1 + 8 {
            return Err(corrupt(path, "size does not match the resolution"));
        }
        Ok(h)
    }

    fn parse_magic_and_header(bytes: &[u8], path: &Path) -> Result<(u8, CheckpointHeader, usize)> {
        let bad = |m: &str| corrupt(path, m);
        let magic = match bytes.get(..8) {
            Some(m) if m == MAGIC => 5,
            Some(m) if m == MAGIC_V4 => 4,
            Some(m) if &m[..7] == b"PNBRCKP" => return Err(bad("written by an older penumbra")),
            _ => return Err(bad("wrong magic")),
        };
        let (h, pos) = parse_header(bytes, path)?;
        Ok((magic, h, pos))
    }

    /// Parses the bytes of a checkpoint or part file; `path` names it in errors. Never
    /// panics, and allocates only for a film whose bytes are all present.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Self> {
        let bad = |m: &str| corrupt(path, m);
        if bytes.len() < 16 {
            return Err(bad("wrong magic"));
        }
        match &bytes[..8] {
            m if m == MAGIC || m == MAGIC_V4 => {}
            m if &m[..7] == b"PNBRCKP" => return Err(bad("written by an older penumbra")),
            _ => return Err(bad("wrong magic")),
        }
        // The checksum first: a corrupt file says so, whatever field the damage hit.
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        if fnv1a(body, 0xcbf2_9ce4_8422_2325).to_le_bytes() != tail {
            return Err(bad("checksum mismatch"));
        }
        let (magic, h, pos) = Self::parse_magic_and_header(bytes, path)?;
        if pos > body.len() {
            return Err(bad("truncated"));
        }
        let pixels = h.width * h.height;
        let (exact, film_end) = if magic == 4 {
            // PNBRCKP4: i128 counts of 2^-48, converted exactly.
            let film_bytes = pixels * EXACT_VALUES * 16;
            let counts = body
                .get(pos..pos + film_bytes)
                .ok_or_else(|| bad("size does not match the resolution"))?;
            let mut exact = ExactFilm::new(h.width, h.height);
            exact.samples = h.film_samples;
            for (j, q) in counts.chunks_exact(16).enumerate() {
                let q = i128::from_le_bytes(q.try_into().map_err(|_| bad("truncated"))?);
                exact.add_parts(j / EXACT_VALUES, j % EXACT_VALUES, q, -48);
            }
            (exact, pos + film_bytes)
        } else {
            let (exact, used) =
                ExactFilm::read_state(&body[pos..], h.width, h.height, h.film_samples)
                    .map_err(|e| bad(&e.to_string()))?;
            (exact, pos + used)
        };
        let left = body.len() - film_end;
        if left != 1 && left != 1 + 16 + pixels * SPPM_PIXEL_BYTES {
            return Err(bad("size does not match the resolution"));
        }
        let mut r = Reader {
            b: body,
            pos: film_end,
        };
        let sppm = match r.take(1).ok_or_else(|| bad("truncated"))?[0] {
            0 if left == 1 => None,
            1 if left > 1 => {
                let mut u = || r.u64().ok_or_else(|| bad("truncated"));
                let (iterations, photons_emitted) = (u()?, u()?);
                let mut st = crate::integrator::sppm::SppmState {
                    iterations,
                    photons_emitted,
                    ld: Vec::with_capacity(pixels),
                    big_n: Vec::with_capacity(pixels),
                    tau: Vec::with_capacity(pixels),
                    radius: Vec::with_capacity(pixels),
                };
                for _ in 0..pixels {
                    let mut v = [0.0f64; 8];
                    for x in v.iter_mut() {
                        *x = r.f64().ok_or_else(|| bad("truncated"))?;
                    }
                    if !v.iter().all(|x| x.is_finite()) || v[3] < 0.0 || v[7] < 0.0 {
                        return Err(bad("sppm state"));
                    }
                    st.ld.push(glam::DVec3::new(v[0], v[1], v[2]));
                    st.big_n.push(v[3]);
                    st.tau.push(glam::DVec3::new(v[4], v[5], v[6]));
                    st.radius.push(v[7]);
                }
                Some(st)
            }
            _ => return Err(bad("unknown section")),
        };
        Ok(Checkpoint {
            version: h.version,
            scene_hash: h.scene_hash,
            seed: h.seed,
            pass_spp: h.pass_spp,
            sampler_points: h.sampler_points,
            first_sample: h.first_sample,
            samples: h.samples,
            plan_spp: h.plan_spp,
            plan_start: h.plan_start,
            part: h.part,
            stats: h.stats,
            filter: h.filter,
            exact,
            sppm,
        })
    }

    /// The f64 film of the sums.
    pub fn film(&self) -> Film {
        self.exact.to_film(self.filter)
    }
}

/// What `render --part i/N` renders: part `index` of `count` of the samples
/// [`start_spp`, `plan_spp`) of every pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartPlan {
    pub index: u32,
    pub count: u32,
    /// Target spp of the render the parts make up.
    pub plan_spp: u64,
    /// Samples before this plan (a plan that extends an earlier render); a multiple of the
    /// pass size.
    pub start_spp: u64,
}

/// The sample range [a, b) of each pixel that part `index` of `count` holds: the passes of
/// [start, plan) split into `count` contiguous runs of whole passes, as evenly as possible.
pub fn part_range(plan: &PartPlan, pass: u32) -> Result<(u64, u64)> {
    let p = pass as u64;
    if p == 0 {
        return Err(Error::Invalid("the pass size is zero".into()));
    }
    if plan.count == 0 || plan.index >= plan.count {
        return Err(Error::Invalid(format!(
            "--part {}/{}: the index must be below the part count",
            plan.index, plan.count
        )));
    }
    if !plan.start_spp.is_multiple_of(p) || plan.start_spp >= plan.plan_spp {
        return Err(Error::Invalid(format!(
            "--start-spp {} must be a multiple of the pass size ({p} spp for this image) and below --spp {}",
            plan.start_spp, plan.plan_spp
        )));
    }
    let passes = (plan.plan_spp - plan.start_spp).div_ceil(p);
    if plan.count as u64 > passes {
        return Err(Error::Invalid(format!(
            "--part {}/{}: the render has only {passes} passes of {p} spp, so at most {passes} parts",
            plan.index, plan.count
        )));
    }
    // In u128: no overflow for any plan.
    let at = |k: u128| (plan.start_spp as u128 + k * p as u128).min(plan.plan_spp as u128) as u64;
    let (i, n, passes) = (plan.index as u128, plan.count as u128, passes as u128);
    Ok((at(i * passes / n), at((i + 1) * passes / n)))
}

/// Renders one part of a split render (see [`PartPlan`]): its passes, exactly as the
/// one-process render draws them, summed exactly. The result is a part file's content.
pub fn render_part(
    job: &Job,
    plan: &PartPlan,
    seed: u64,
    threads: Option<usize>,
    scene_hash: u64,
) -> Result<Checkpoint> {
    let settings = PartSettings {
        seed,
        threads,
        scene_hash,
        stop: None,
        checkpoint: None,
    };
    Ok(render_part_with(job, plan, &settings, None, &|_| {})?.part)
}

/// How [`render_part_with`] renders a part: [`render_part`]'s arguments, and what makes a
/// long part stoppable and resumable.
#[derive(Clone, Debug)]
pub struct PartSettings {
    pub seed: u64,
    pub threads: Option<usize>,
    pub scene_hash: u64,
    /// Checked after every pass, as [`ProgressiveSettings::stop`]: once set, the part ends
    /// with [`StopReason::Interrupted`] and the passes done so far.
    pub stop: Option<Arc<AtomicBool>>,
    /// The part's checkpoint: its samples so far (a part file's header with fewer samples
    /// than the plan gives it), written every `every` and when the part is interrupted, not
    /// when it completes (the part file is then the whole result).
    pub checkpoint: Option<Checkpointing>,
}

/// What [`render_part_with`] rendered.
#[derive(Clone, Debug)]
pub struct PartRun {
    /// The part's sums: the samples [first_sample, first_sample + samples) of every pixel;
    /// all of the part's samples unless `reason` is [`StopReason::Interrupted`].
    pub part: Checkpoint,
    /// [`StopReason::SppReached`] (the part is complete) or [`StopReason::Interrupted`].
    pub reason: StopReason,
    /// As in [`Progress`]: failed checkpoint writes, and why the latest one failed (`None`
    /// once a later one succeeded; when the part was interrupted, the interrupted state's).
    pub checkpoint_failures: u64,
    pub checkpoint_error: Option<String>,
}

/// [`render_part`], stoppable and resumable: continues the part checkpoint `resume` (which
/// must be of this part of this plan, scene, seed and version), writes checkpoints as
/// `settings` asks, and stops after the pass under way once `settings.stop` is set. A part
/// resumed and completed is bit-identical to the part rendered in one go. `on_pass` sees the
/// state after every pass (and after its checkpoint, if one was due).
pub fn render_part_with(
    job: &Job,
    plan: &PartPlan,
    settings: &PartSettings,
    resume: Option<Checkpoint>,
    on_pass: &(dyn Fn(&PartRun) + Sync),
) -> Result<PartRun> {
    let scene = &job.scene;
    if matches!(job.integrator, crate::integrator::Integrator::Sppm(_)) {
        return Err(Error::Invalid(
            "an sppm render cannot be split into parts (each iteration continues the \
             previous one's radii and photon counts): render it in one process, with \
             checkpoints"
                .into(),
        ));
    }
    let pass = pass_spp(scene.width, scene.height);
    let (a, b) = part_range(plan, pass)?;
    let mut run = PartRun {
        part: Checkpoint {
            version: crate::VERSION.to_string(),
            scene_hash: settings.scene_hash,
            seed: settings.seed,
            pass_spp: pass,
            sampler_points: scene.sampler.sample_count,
            first_sample: a,
            samples: 0,
            plan_spp: plan.plan_spp,
            plan_start: plan.start_spp,
            part: Some((plan.index, plan.count)),
            stats: RenderStats::default(),
            filter: scene.filter,
            exact: ExactFilm::new(scene.width, scene.height),
            sppm: None,
        },
        reason: StopReason::SppReached,
        checkpoint_failures: 0,
        checkpoint_error: None,
    };
    if let Some(c) = resume {
        check_part_resume(&c, &run.part, b)?;
        run.part.samples = c.samples;
        run.part.stats = c.stats;
        run.part.exact = c.exact;
    }
    let pool = crate::render::thread_pool(settings.threads)?;
    let mut last_checkpoint = Instant::now();
    let mut checkpointed = run.part.samples;
    let mut at = a + run.part.samples;
    while at < b {
        if settings
            .stop
            .as_ref()
            .is_some_and(|s| s.load(Ordering::Relaxed))
        {
            run.reason = StopReason::Interrupted;
            break;
        }
        let spp = (pass as u64).min(b - at) as u32;
        let out = render(
            scene,
            &job.integrator,
            &RenderSettings {
                spp,
                seed: settings.seed,
                threads: settings.threads,
                sampler: None,
                first_sample: at,
            },
            &|_, _| {},
        )?;
        let part = &mut run.part;
        let exact = &mut part.exact;
        pool.install(|| exact.add(&out.film))
            .map_err(|e| Error::Invalid(e.to_string()))?;
        part.stats.paths += out.stats.paths;
        part.stats.path += out.stats.path;
        part.stats.nonfinite += out.stats.nonfinite;
        part.stats.seconds += out.stats.seconds;
        at += spp as u64;
        part.samples = at - a;
        if let Some(cp) = &settings.checkpoint {
            if at < b && last_checkpoint.elapsed() >= cp.every {
                let r = write_checkpoint_retrying(&run.part, &cp.path);
                note_part_checkpoint(&mut run, r);
                if run.checkpoint_error.is_none() {
                    checkpointed = run.part.samples;
                }
                last_checkpoint = Instant::now();
            }
        }
        on_pass(&run);
    }
    if run.reason == StopReason::Interrupted {
        if let Some(cp) = &settings.checkpoint {
            if checkpointed != run.part.samples || run.checkpoint_error.is_some() {
                let r = write_checkpoint_retrying(&run.part, &cp.path);
                note_part_checkpoint(&mut run, r);
            }
        }
    }
    Ok(run)
}

fn note_part_checkpoint(run: &mut PartRun, r: Result<()>) {
    match r {
        Ok(()) => run.checkpoint_error = None,
        Err(e) => {
            run.checkpoint_failures += 1;
            run.checkpoint_error = Some(e.to_string());
        }
    }
}

/// Refuses to continue a part from `c` unless it is a checkpoint of the part `fresh`
/// describes (same plan, part, scene, seed, sampler, resolution and version), within the
/// part's samples (which end at `end`).
fn check_part_resume(c: &Checkpoint, fresh: &Checkpoint, end: u64) -> Result<()> {
    let refuse = |what: String| {
        Err(Error::Invalid(format!(
            "cannot resume the part: the checkpoint was made {what}"
        )))
    };
    let (i, n) = fresh.part.unwrap_or((0, 0));
    match c.part {
        None => return refuse("by a render without --part (resume it without --part)".into()),
        Some(p) if p != (i, n) => {
            return refuse(format!("for part {}/{} (this is part {i}/{n})", p.0, p.1))
        }
        Some(_) => {}
    }
    if (c.plan_spp, c.plan_start) != (fresh.plan_spp, fresh.plan_start) {
        return refuse(format!(
            "for a plan of {} spp from {} (this part's plan: {} spp from {})",
            c.plan_spp, c.plan_start, fresh.plan_spp, fresh.plan_start
        ));
    }
    if c.version != fresh.version {
        return refuse(format!(
            "by penumbra {} (this is {})",
            c.version, fresh.version
        ));
    }
    if c.scene_hash != fresh.scene_hash {
        return refuse("from another scene (or other -D values or mesh files)".into());
    }
    if c.seed != fresh.seed {
        return refuse(format!(
            "with seed {} (this render uses {})",
            c.seed, fresh.seed
        ));
    }
    if (c.exact.width, c.exact.height) != (fresh.exact.width, fresh.exact.height)
        || c.pass_spp != fresh.pass_spp
        || c.filter != fresh.filter
        || c.sampler_points != fresh.sampler_points
    {
        return refuse("for another resolution, filter or sampler".into());
    }
    if c.sppm.is_some()
        || c.first_sample != fresh.first_sample
        || c.first_sample
            .checked_add(c.samples)
            .is_none_or(|e| e > end)
    {
        return refuse("for other samples than this part's".into());
    }
    Ok(())
}

/// The parts to add, in order, and what they make up: checked from their headers alone.
struct MergePlan {
    /// Indices into the given parts, by increasing first sample.
    order: Vec<usize>,
    end: u64,
    stats: RenderStats,
}

/// Checks a set of parts from their headers (see [`merge_parts`]) and orders them.
fn plan_merge(parts: &[(PathBuf, CheckpointHeader)], target_spp: Option<u64>) -> Result<MergePlan> {
    let name = |p: &Path| p.display().to_string();
    let mut sorted: Vec<usize> = (0..parts.len()).collect();
    sorted.sort_by_key(|&i| {
        let c = &parts[i].1;
        (c.first_sample, c.first_sample + c.samples)
    });
    let Some(&first_index) = sorted.first() else {
        return Err(Error::Invalid("merge: no part files given".into()));
    };
    let (first_path, first) = &parts[first_index];
    for &i in &sorted {
        let (path, c) = &parts[i];
        let differs = |what: &str| {
            Err(Error::Invalid(format!(
                "{} was rendered {what} than {}",
                name(path),
                name(first_path)
            )))
        };
        if c.part.is_none() {
            return Err(Error::Invalid(format!(
                "{} is a checkpoint, not a part file of `render --part`",
                name(path)
            )));
        }
        if c.version != first.version {
            return differs(&format!(
                "by another penumbra version ({} vs {})",
                c.version, first.version
            ));
        }
        if c.scene_hash != first.scene_hash {
            return differs("from another scene (or other -D values or mesh files)");
        }
        if c.seed != first.seed {
            return differs(&format!("with another seed ({} vs {})", c.seed, first.seed));
        }
        if (c.width, c.height) != (first.width, first.height) || c.filter != first.filter {
            return differs("at another resolution or with another filter");
        }
        if c.pass_spp != first.pass_spp || c.sampler_points != first.sampler_points {
            return differs("with another pass size or sampler (another spp plan)");
        }
    }
    let pass = first.pass_spp as u64;
    // The render the parts make up ends where their plans end (so that missing last parts
    // are named), unless a smaller target is asked for.
    let end =
        target_spp.unwrap_or_else(|| parts.iter().map(|(_, c)| c.plan_spp).max().unwrap_or(0));
    let label = |p: &Path, c: &CheckpointHeader| {
        let (i, n) = c.part.unwrap_or((0, 0));
        format!(
            "{} (part {i}/{n} of {} spp: samples {}..{})",
            name(p),
            c.plan_spp,
            c.first_sample,
            c.first_sample + c.samples
        )
    };
    let mut order = Vec::new();
    let mut stats = RenderStats::default();
    let mut covered = 0u64;
    let mut prev: Option<usize> = None;
    for &i in &sorted {
        let (path, c) = &parts[i];
        let (a, b) = (c.first_sample, c.first_sample + c.samples);
        if a >= end {
            continue;
        }
        if let Some(pi) = prev {
            let (pp, pc) = &parts[pi];
            if (pc.first_sample, pc.samples) == (a, c.samples) {
                return Err(Error::Invalid(format!(
                    "duplicate parts: {} and {}",
                    label(pp, pc),
                    label(path, c)
                )));
            }
        }
        if a < covered {
            let Some(pi) = prev else {
                return Err(Error::Invalid("overlapping parts".into()));
            };
            let (pp, pc) = &parts[pi];
            return Err(Error::Invalid(format!(
                "overlapping parts: {} and {}",
                label(pp, pc),
                label(path, c)
            )));
        }
        if a > covered {
            return Err(missing(covered, a, parts));
        }
        if b > end {
            return Err(Error::Invalid(format!(
                "--spp {end} falls inside {}: merge up to a part boundary",
                label(path, c)
            )));
        }
        if !a.is_multiple_of(pass) || (!b.is_multiple_of(pass) && b != end) {
            return Err(Error::Invalid(format!(
                "{} does not start and end on a pass boundary (passes of {pass} spp) where other parts continue it",
                label(path, c)
            )));
        }
        stats.paths = stats.paths.saturating_add(c.stats.paths);
        stats.path.rays = stats.path.rays.saturating_add(c.stats.path.rays);
        stats.path.bounces = stats.path.bounces.saturating_add(c.stats.path.bounces);
        stats.path.rr_terminated = stats
            .path
            .rr_terminated
            .saturating_add(c.stats.path.rr_terminated);
        stats.nonfinite = stats.nonfinite.saturating_add(c.stats.nonfinite);
        stats.seconds += c.stats.seconds;
        covered = b;
        prev = Some(i);
        order.push(i);
    }
    if covered < end {
        return Err(missing(covered, end, parts));
    }
    Ok(MergePlan { order, end, stats })
}

/// The merged render's checkpoint, from the first part's header and the summed film.
fn merged_checkpoint(first: &CheckpointHeader, plan: MergePlan, exact: ExactFilm) -> Checkpoint {
    Checkpoint {
        version: first.version.clone(),
        scene_hash: first.scene_hash,
        seed: first.seed,
        pass_spp: first.pass_spp,
        sampler_points: first.sampler_points,
        first_sample: 0,
        samples: plan.end,
        plan_spp: plan.end,
        plan_start: 0,
        part: None,
        stats: plan.stats,
        filter: first.filter,
        exact,
        sppm: None,
    }
}

/// Merges part files (any order) into the render they make up: the samples [0, S) of every
/// pixel, S the largest spp plan among the parts (or `target_spp`, leaving out parts beyond
/// it). Refuses,
/// with one line naming the file(s), parts of another penumbra version, scene, seed,
/// resolution, filter, pass size or sampler, duplicates and overlaps, parts that do not start
/// or end on a pass boundary where another part continues, and gaps (naming the missing parts
/// where their plan tells). The sums are added exactly, so the result is bit-identical to the
/// one-process render of S spp.
///
/// The parts are given in memory here; [`merge_part_files`] reads them one at a time.
pub fn merge_parts(
    parts: Vec<(PathBuf, Checkpoint)>,
    target_spp: Option<u64>,
) -> Result<Checkpoint> {
    let headers: Vec<(PathBuf, CheckpointHeader)> =
        parts.iter().map(|(p, c)| (p.clone(), c.header())).collect();
    let plan = plan_merge(&headers, target_spp)?;
    let first = &headers[plan.order[0]].1;
    let mut merged = ExactFilm::new(first.width, first.height);
    let mut parts: Vec<Option<Checkpoint>> = parts.into_iter().map(|(_, c)| Some(c)).collect();
    for &i in &plan.order {
        // Each part is dropped once added.
        if let Some(c) = parts[i].take() {
            merged
                .add_exact(&c.exact)
                .map_err(|e| Error::Invalid(e.to_string()))?;
        }
    }
    Ok(merged_checkpoint(first, plan, merged))
}

/// [`merge_parts`] of the part files at `paths`, streaming: the headers are read and checked
/// first, then each file in turn is read whole (checksum verified), added to the one merged
/// film and dropped, so that memory holds the merged film and one part whatever the number
/// of parts. A file that changed between the two reads is refused.
pub fn merge_part_files(paths: &[PathBuf], target_spp: Option<u64>) -> Result<Checkpoint> {
    let mut headers = Vec::with_capacity(paths.len());
    for p in paths {
        headers.push((p.clone(), Checkpoint::read_header(p)?));
    }
    let plan = plan_merge(&headers, target_spp)?;
    let first = headers[plan.order[0]].1.clone();
    let mut merged = ExactFilm::new(first.width, first.height);
    for &i in &plan.order {
        let (path, header) = &headers[i];
        let c = Checkpoint::read(path)?;
        if c.header() != *header {
            return Err(Error::Invalid(format!(
                "{}: the file changed while the parts were merged",
                path.display()
            )));
        }
        merged
            .add_exact(&c.exact)
            .map_err(|e| Error::Invalid(e.to_string()))?;
    }
    Ok(merged_checkpoint(&first, plan, merged))
}

/// The error for samples [a, b) that no part holds: the missing parts of the plans the given
/// parts belong to, or the sample range.
fn missing(a: u64, b: u64, parts: &[(PathBuf, CheckpointHeader)]) -> Error {
    let mut names = Vec::new();
    for (_, c) in parts {
        let Some((_, n)) = c.part else { continue };
        // Name parts only for plans of a sensible size (a corrupt count must not loop long).
        for i in 0..n.min(100_000) {
            let plan = PartPlan {
                index: i,
                count: n,
                plan_spp: c.plan_spp,
                start_spp: c.plan_start,
            };
            if let Ok((x, y)) = part_range(&plan, c.pass_spp) {
                if x < b && y > a {
                    let s = format!("{i}/{n} of {} spp (samples {x}..{y})", c.plan_spp);
                    if !names.contains(&s) {
                        names.push(s);
                    }
                }
            }
        }
    }
    if names.is_empty() {
        Error::Invalid(format!("missing samples {a}..{b}: no part holds them"))
    } else {
        Error::Invalid(format!(
            "missing samples {a}..{b}: parts {} are not among the files",
            names.join(", ")
        ))
    }
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let s = self.b.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        Some(s)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

/// The largest checkpoint or part file read: its film at the `render_pixels` limit, 18 bytes
/// per value, plus room for spilled values (an exact sum over f64's whole range takes at
/// most 2,100 bits, 272 bytes with its key): a bound before allocating, and special files
/// (a checkpoint path at /dev/zero, a FIFO) are refused by [`crate::io::open_regular`].
fn checkpoint_file_limit() -> Result<u64> {
    let pixels = crate::limits::current()?.render_pixels;
    Ok(pixels
        .saturating_mul(EXACT_VALUES as u64)
        .saturating_mul(18 + 272)
        .saturating_add(1 << 20))
}
