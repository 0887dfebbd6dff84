//! Convergence studies: a scene rendered along a ladder of sample counts (1, 4, 16, ...
//! spp), with the wall time and the error against a reference image at every step, and the
//! fitted slope of log RMSE against log spp. With the `independent` and `zsobol` samplers
//! each step continues the previous one's samples; with the samplers that need their point
//! count up front (stratified, multijitter, orthogonal, ldsampler) each step is a render of
//! its own at that count, as a user rendering at that spp gets it, timed alone.
//!
//! An unbiased Monte Carlo estimator with per-sample variance σ² has an expected MSE of
//! σ²/n against the true image, so log RMSE falls with slope −1/2 in log n. Against a
//! reference rendered with `n_ref` samples of variance σ²_ref the expected MSE is
//! σ²/n + σ²_ref/n_ref + bias²: the reference's own noise puts a floor
//! `sqrt(mean σ²_ref / n_ref)` under the curve ([`reference_noise_floor`]), and a bias
//! flattens the curve above that floor. [`fit_slope`] fits the slope over the steps well
//! above the floor ([`FLOOR_FACTOR`]), where the floor changes the RMSE by at most a few
//! percent.
//!
//! Used by the validation study against Mitsuba (`validation`), its tests, and any command
//! that wants error-versus-spp curves.

use crate::error::{Error, Result};
use crate::film::Film;
use crate::render::{render, Job, RenderSettings, RenderStats};
use crate::sampler::{Sampler, SamplerKind};
use crate::study::metrics::{error_metrics, ErrorMetrics};

/// Steps whose RMSE is at most this multiple of the reference's noise floor are left out of
/// the slope fit. At RMSE = 3·floor the floor makes up 1/9 of the MSE and raises the RMSE by
/// 6%, which bends the fitted slope by a few hundredths at most.
pub const FLOOR_FACTOR: f64 = 3.0;

/// The slope of log RMSE against log spp of an unbiased estimator.
pub const IDEAL_SLOPE: f64 = -0.5;

/// Fewest steps a slope verdict is based on.
pub const MIN_FIT_STEPS: usize = 3;

/// The sample counts 1, 4, 16, ... up to `max_spp`, ending with `max_spp` itself when it is
/// not a power of four. Empty when `max_spp` is 0.
pub fn spp_ladder(max_spp: u32) -> Vec<u32> {
    let mut steps = Vec::new();
    let mut n = 1u32;
    while n <= max_spp {
        steps.push(n);
        match n.checked_mul(4) {
            Some(m) => n = m,
            None => break,
        }
    }
    if steps.last().is_some_and(|&last| last != max_spp) {
        steps.push(max_spp);
    }
    steps
}

/// One step of a ladder: the image after `spp` samples per pixel in total.
#[derive(Clone, Debug)]
pub struct LadderStep {
    /// Samples per pixel so far.
    pub spp: u32,
    /// Wall time of all sampling so far, in seconds (scene loading not included).
    pub seconds: f64,
    /// Error of the image so far against the reference.
    pub metrics: ErrorMetrics,
}

/// A finished ladder.
#[derive(Clone, Debug)]
pub struct Ladder {
    pub steps: Vec<LadderStep>,
    /// The film after the last step (all samples).
    pub film: Film,
    /// Render statistics summed over all steps.
    pub stats: RenderStats,
}

impl Ladder {
    /// Mean over pixel-channels of the final film's per-sample variance: σ² of the ideal
    /// curve σ/√spp.
    pub fn mean_sample_variance(&self) -> f64 {
        mean_of(&self.film.sample_variance())
    }

    /// (spp, RMSE) of every step.
    pub fn rmse_points(&self) -> Vec<(f64, f64)> {
        self.steps
            .iter()
            .map(|s| (s.spp as f64, s.metrics.rmse))
            .collect()
    }
}

/// Mean over all pixel-channels.
pub fn mean_of(values: &[[f32; 3]]) -> f64 {
    let n = (values.len() * 3).max(1) as f64;
    values
        .iter()
        .flat_map(|p| p.iter())
        .map(|&v| v as f64)
        .sum::<f64>()
        / n
}

/// Renders `scene` at the cumulative sample counts `steps` (strictly increasing): with a
/// progressive sampler step k draws samples `steps[k-1] .. steps[k]` of every pixel (see
/// [`RenderSettings::first_sample`]) and adds them to the film, so the last image is exactly
/// the one a single render at `steps.last()` spp gives; with the others step k is a render
/// of its own with the sampler's points per pass set to `steps[k]` (rounded by the plugin;
/// a step that rounds to the previous one's count is left out). After each step `on_step`
/// sees its time and error against `reference` (same resolution).
pub fn run_ladder(
    job: &Job,
    steps: &[u32],
    seed: u64,
    threads: Option<usize>,
    reference: &[[f32; 3]],
    on_step: &mut dyn FnMut(&LadderStep),
) -> Result<Ladder> {
    run_ladder_with_film(
        job,
        steps,
        seed,
        threads,
        reference,
        None,
        &mut |step, _| on_step(step),
    )
}

/// [`run_ladder`], with `on_step` also seeing the film after each step (for measures that
/// need the per-pixel variance, like the z-test), and stopping after the first step whose
/// time reaches `max_seconds` (to compare integrators of very different cost per sample
/// over the same time budget).
pub fn run_ladder_with_film(
    job: &Job,
    steps: &[u32],
    seed: u64,
    threads: Option<usize>,
    reference: &[[f32; 3]],
    max_seconds: Option<f64>,
    on_step: &mut dyn FnMut(&LadderStep, &Film),
) -> Result<Ladder> {
    let scene = &job.scene;
    if reference.len() != scene.width * scene.height {
        return Err(Error::Invalid(format!(
            "reference has {} pixels, the scene renders {}x{}",
            reference.len(),
            scene.width,
            scene.height
        )));
    }
    if steps.is_empty() || steps[0] == 0 || steps.windows(2).any(|w| w[1] <= w[0]) {
        return Err(Error::Invalid(format!(
            "spp ladder must be positive and strictly increasing, got {steps:?}"
        )));
    }
    let mut film = Film::new(scene.width, scene.height, scene.filter);
    let mut stats = RenderStats::default();
    let mut out = Vec::with_capacity(steps.len());
    let mut done = 0u32;
    let kind = scene.sampler.kind;
    // A progressive sampler continues one render through the ladder, with passes as large as
    // its last step (zsobol: a power of four, whose prefixes at powers of four are nets).
    let last = *steps.last().unwrap_or(&1);
    let whole = Sampler {
        kind,
        sample_count: match kind {
            SamplerKind::ZSobol => {
                let mut p = 1u32;
                while p < last {
                    p = p.saturating_mul(4);
                }
                p
            }
            _ => last,
        },
    };
    // SPPM's iterations depend on each other: each step is a render of its own, and its
    // time that render's (what a user asking for that many iterations gets).
    let sppm = matches!(job.integrator, crate::integrator::Integrator::Sppm(_));
    for &requested in steps {
        let (spp, settings) = if sppm {
            film = Film::new(scene.width, scene.height, scene.filter);
            stats = RenderStats::default();
            let settings = RenderSettings {
                spp: requested,
                first_sample: 0,
                seed,
                threads,
                sampler: None,
            };
            (requested, settings)
        } else if kind.progressive() {
            let settings = RenderSettings {
                spp: requested - done,
                first_sample: done as u64,
                seed,
                threads,
                sampler: Some(whole),
            };
            (requested, settings)
        } else {
            // The others need their point count up front: each step is a render of its own
            // at that count (rounded as the plugin does), what a user rendering at that spp
            // gets, and its time is that render's.
            let sampler = Sampler::new(kind, requested).0;
            if sampler.sample_count <= done {
                continue; // rounded to the previous step's count
            }
            film = Film::new(scene.width, scene.height, scene.filter);
            stats = RenderStats::default();
            let spp = sampler.sample_count;
            let settings = RenderSettings {
                spp,
                first_sample: 0,
                seed,
                threads,
                sampler: Some(sampler),
            };
            (spp, settings)
        };
        let part = render(scene, &job.integrator, &settings, &|_, _| {})?;
        film.add(&part.film);
        stats.paths += part.stats.paths;
        stats.path += part.stats.path;
        stats.nonfinite += part.stats.nonfinite;
        stats.seconds += part.stats.seconds;
        done = spp;
        let step = LadderStep {
            spp,
            seconds: stats.seconds,
            metrics: error_metrics(&film.image(), reference),
        };
        on_step(&step, &film);
        let seconds = step.seconds;
        out.push(step);
        if max_seconds.is_some_and(|m| seconds >= m) {
            break;
        }
    }
    Ok(Ladder {
        steps: out,
        film,
        stats,
    })
}

/// The RMSE against the reference that a perfect image (noise-free and unbiased) would
/// show: `sqrt(mean(var_ref) / spp_ref)`, with `var_ref` the reference's per-pixel
/// per-sample variance. This is the reference's own contribution to the expected MSE.
pub fn reference_noise_floor(reference_variance: &[[f32; 3]], reference_spp: f64) -> f64 {
    (mean_of(reference_variance) / reference_spp).sqrt()
}

/// A least-squares line through (ln x, ln y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogLogLine {
    pub slope: f64,
    /// ln y at x = 1.
    pub intercept: f64,
}

impl LogLogLine {
    pub fn eval(&self, x: f64) -> f64 {
        (self.intercept + self.slope * x.ln()).exp()
    }
}

/// Ordinary least squares of ln y on ln x; `None` with fewer than two distinct positive x,
/// or any point not positive and finite.
pub fn fit_log_log(points: &[(f64, f64)]) -> Option<LogLogLine> {
    if points.len() < 2
        || points
            .iter()
            .any(|&(x, y)| !(x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite()))
    {
        return None;
    }
    let n = points.len() as f64;
    let lx: Vec<f64> = points.iter().map(|p| p.0.ln()).collect();
    let ly: Vec<f64> = points.iter().map(|p| p.1.ln()).collect();
    let mx = lx.iter().sum::<f64>() / n;
    let my = ly.iter().sum::<f64>() / n;
    let sxx: f64 = lx.iter().map(|x| (x - mx) * (x - mx)).sum();
    let sxy: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some(LogLogLine {
        slope,
        intercept: my - slope * mx,
    })
}

/// The slope of log RMSE against log spp, fitted above the reference's noise floor.
#[derive(Clone, Debug, PartialEq)]
pub struct SlopeFit {
    /// The fitted line, if at least two steps were used.
    pub line: Option<LogLogLine>,
    /// Steps used: the leading steps whose RMSE exceeds `floor_factor · floor`.
    pub used: usize,
    /// Steps given.
    pub total: usize,
    pub floor: f64,
    pub floor_factor: f64,
}

impl SlopeFit {
    pub fn slope(&self) -> Option<f64> {
        self.line.map(|l| l.slope)
    }

    /// The check: at least [`MIN_FIT_STEPS`] steps above the floor and a slope within
    /// `tolerance` of −1/2.
    pub fn passed(&self, tolerance: f64) -> bool {
        self.used >= MIN_FIT_STEPS
            && self
                .slope()
                .is_some_and(|s| (s - IDEAL_SLOPE).abs() <= tolerance)
    }
}

/// Fits log RMSE against log spp over the leading `points` (spp, RMSE), in increasing spp,
/// whose RMSE is above `floor_factor · floor`: the fit stops at the first step that comes
/// within that factor of the floor (the curve flattens there whatever the renderer does).
pub fn fit_slope(points: &[(f64, f64)], floor: f64, floor_factor: f64) -> SlopeFit {
    let used = points
        .iter()
        .take_while(|&&(_, rmse)| rmse > floor_factor * floor)
        .count();
    SlopeFit {
        line: fit_log_log(&points[..used]),
        used,
        total: points.len(),
        floor,
        floor_factor,
    }
}
