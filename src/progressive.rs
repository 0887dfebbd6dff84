//! Long renders: samples are drawn in passes of a fixed size, each continuing the previous
//! one's sample indices, so that a render can stop on a time limit or a target error, write
//! checkpoints of its running sums, and be resumed. The pass schedule depends only on the
//! image size and the target spp, and films are summed pass by pass in the same order, so a
//! render resumed from a checkpoint is bit-identical to an uninterrupted one.

use crate::error::{Error, Result};
use crate::film::Film;
use crate::render::{render, RenderSettings, RenderStats};
use crate::scene::Scene;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
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
}

/// Why a progressive render stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    SppReached,
    TimeLimit,
    TargetError,
}

/// The running state of a render: sums and counters.
#[derive(Clone, Debug)]
pub struct Progress {
    pub film: Film,
    /// Samples per pixel drawn so far.
    pub samples: u64,
    pub stats: RenderStats,
}

/// Minimum samples per pixel before a target error is trusted (variance estimates from fewer
/// samples are too noisy to stop on).
pub const MIN_SPP_FOR_TARGET: u64 = 16;

/// Estimated relative standard error of the current estimate.
pub fn relative_standard_error(film: &Film, target: ErrorTarget) -> f64 {
    let mean = film.image();
    let var = film.sample_variance();
    match target {
        ErrorTarget::ImageMean => {
            let n = mean.len() as f64;
            let mut worst: f64 = 0.0;
            for c in 0..3 {
                let m: f64 = mean.iter().map(|p| p[c] as f64).sum::<f64>() / n;
                let v: f64 = var
                    .iter()
                    .zip(&film.weight)
                    .map(|(v, w)| if *w > 0.0 { v[c] as f64 / w } else { 0.0 })
                    .sum::<f64>();
                if m > 0.0 {
                    worst = worst.max(v.sqrt() / n / m);
                }
            }
            worst
        }
        ErrorTarget::PerPixel => {
            let lum =
                |p: &[f32; 3]| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64;
            let (mut acc, mut count) = (0.0, 0usize);
            for ((m, v), w) in mean.iter().zip(&var).zip(&film.weight) {
                let lm = lum(m);
                if lm > 0.0 && *w > 0.0 {
                    acc += (lum(v) / w).sqrt() / lm;
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
    scene: &Scene,
    settings: &ProgressiveSettings,
    resume: Option<Checkpoint>,
    on_pass: &(dyn Fn(&Progress) + Sync),
) -> Result<(Progress, StopReason)> {
    let pass = pass_spp(scene.width, scene.height);
    let mut progress = match resume {
        Some(c) => {
            c.check_matches(scene, settings, pass)?;
            Progress {
                film: c.film,
                samples: c.samples,
                stats: c.stats,
            }
        }
        None => Progress {
            film: Film::new(scene.width, scene.height, scene.filter),
            samples: 0,
            stats: RenderStats::default(),
        },
    };
    let start = Instant::now();
    let mut last_checkpoint = Instant::now();
    let reason = loop {
        if progress.samples >= settings.spp as u64 {
            break StopReason::SppReached;
        }
        if let Some(limit) = settings.time_limit {
            if start.elapsed() >= limit {
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
        let out = render(
            scene,
            &RenderSettings {
                spp,
                seed: settings.seed,
                threads: settings.threads,
                sampler: None,
                first_sample: progress.samples,
            },
            &|_, _| {},
        )?;
        progress.film.add(&out.film);
        progress.samples += spp as u64;
        progress.stats.paths += out.stats.paths;
        progress.stats.path += out.stats.path;
        progress.stats.nonfinite += out.stats.nonfinite;
        progress.stats.seconds += out.stats.seconds;
        on_pass(&progress);
        if let Some(cp) = &settings.checkpoint {
            if last_checkpoint.elapsed() >= cp.every {
                Checkpoint::from_progress(&progress, settings, pass, scene).write(&cp.path)?;
                last_checkpoint = Instant::now();
            }
        }
    };
    if let Some(cp) = &settings.checkpoint {
        Checkpoint::from_progress(&progress, settings, pass, scene).write(&cp.path)?;
    }
    Ok((progress, reason))
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
/// defaults and -D overrides) and the bytes of every file it loads (meshes, grids, images).
pub fn scene_hash(desc: &crate::scene::description::SceneDescription) -> u64 {
    let mut h = fnv1a(format!("{desc:?}").as_bytes(), 0xcbf2_9ce4_8422_2325);
    for path in desc.files() {
        if let Ok(bytes) = std::fs::read(path) {
            h = fnv1a(&bytes, h);
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
    pub samples: u64,
    pub stats: RenderStats,
    pub film: Film,
}

const MAGIC: &[u8; 8] = b"PNBRCKP2";

impl Checkpoint {
    fn from_progress(p: &Progress, s: &ProgressiveSettings, pass_spp: u32, scene: &Scene) -> Self {
        Checkpoint {
            version: crate::VERSION.to_string(),
            scene_hash: s.scene_hash,
            seed: s.seed,
            pass_spp,
            sampler_points: scene.sampler.sample_count,
            samples: p.samples,
            stats: p.stats,
            film: p.film.clone(),
        }
    }

    fn check_matches(&self, scene: &Scene, s: &ProgressiveSettings, pass_spp: u32) -> Result<()> {
        let refuse = |what: String| {
            Err(Error::Invalid(format!(
                "cannot resume: the checkpoint was made {what}"
            )))
        };
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
        if (self.film.width, self.film.height) != (scene.width, scene.height)
            || self.pass_spp != pass_spp
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

    /// Writes atomically: to a temporary file next to `path`, synced, then renamed over it, so
    /// a crash never leaves a half-written checkpoint.
    pub fn write(&self, path: &Path) -> Result<()> {
        let err = |e: std::io::Error| Error::Io {
            path: path.to_path_buf(),
            cause: e,
        };
        let mut buf = Vec::with_capacity(64 + self.film.sum.len() * 56);
        buf.extend_from_slice(MAGIC);
        let v = self.version.as_bytes();
        buf.extend_from_slice(&(v.len() as u32).to_le_bytes());
        buf.extend_from_slice(v);
        for x in [
            self.scene_hash,
            self.seed,
            self.samples,
            self.film.width as u64,
            self.film.height as u64,
        ] {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        buf.extend_from_slice(&self.pass_spp.to_le_bytes());
        buf.extend_from_slice(&self.sampler_points.to_le_bytes());
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
        for i in 0..self.film.sum.len() {
            for c in 0..3 {
                buf.extend_from_slice(&self.film.sum[i][c].to_le_bytes());
                buf.extend_from_slice(&self.film.sum_sq[i][c].to_le_bytes());
            }
            buf.extend_from_slice(&self.film.weight[i].to_le_bytes());
        }
        let checksum = fnv1a(&buf, 0xcbf2_9ce4_8422_2325);
        buf.extend_from_slice(&checksum.to_le_bytes());
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = path.with_file_name(format!(".{name}.tmp"));
        let mut f = std::fs::File::create(&tmp).map_err(err)?;
        f.write_all(&buf).map_err(err)?;
        f.sync_all().map_err(err)?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(err)
    }

    /// Reads a checkpoint written by [`Checkpoint::write`] for a film of the given filter.
    pub fn read(path: &Path, filter: crate::film::Filter) -> Result<Self> {
        let bad = |m: &str| {
            Error::Invalid(format!(
                "{}: not a valid penumbra checkpoint ({m})",
                path.display()
            ))
        };
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|cause| Error::Io {
                path: path.to_path_buf(),
                cause,
            })?;
        if bytes.len() < 16 || &bytes[..8] != MAGIC {
            return Err(bad("wrong magic"));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        if fnv1a(body, 0xcbf2_9ce4_8422_2325).to_le_bytes() != tail {
            return Err(bad("checksum mismatch"));
        }
        let mut r = Reader { b: body, pos: 8 };
        let vlen = r.u32().ok_or_else(|| bad("truncated"))? as usize;
        let version = String::from_utf8(r.take(vlen).ok_or_else(|| bad("truncated"))?.to_vec())
            .map_err(|_| bad("bad version"))?;
        let mut u = || r.u64().ok_or_else(|| bad("truncated"));
        let (scene_hash, seed, samples, width, height) = (u()?, u()?, u()?, u()?, u()?);
        let pixels = width
            .checked_mul(height)
            .filter(|&n| n <= crate::scene::description::MAX_PIXELS);
        let pixels = pixels.ok_or_else(|| bad("resolution"))? as usize;
        let pass_spp = r.u32().ok_or_else(|| bad("truncated"))?;
        let sampler_points = r.u32().ok_or_else(|| bad("truncated"))?;
        let mut u = || r.u64().ok_or_else(|| bad("truncated"));
        let (paths, rays, bounces, rr, nonfinite) = (u()?, u()?, u()?, u()?, u()?);
        let seconds = r.f64().ok_or_else(|| bad("truncated"))?;
        if r.b.len() - r.pos != pixels * 7 * 8 {
            return Err(bad("size does not match the resolution"));
        }
        let mut film = Film::new(width as usize, height as usize, filter);
        for i in 0..pixels {
            for c in 0..3 {
                film.sum[i][c] = r.f64().ok_or_else(|| bad("truncated"))?;
                film.sum_sq[i][c] = r.f64().ok_or_else(|| bad("truncated"))?;
            }
            film.weight[i] = r.f64().ok_or_else(|| bad("truncated"))?;
        }
        Ok(Checkpoint {
            version,
            scene_hash,
            seed,
            pass_spp,
            sampler_points,
            samples,
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
            film,
        })
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
