//! The validation study against Mitsuba 3.9.1: the scene list (`validation/scenes.toml`),
//! the Mitsuba references (`validation/references/*.exr`, made by
//! `validation/mitsuba/render_all.py`), the three checks and the markdown report.
//!
//! For a scene rendered along a ladder of sample counts (see [`crate::study::convergence`]), with
//! the last step's image and per-sample variance:
//!
//! 1. **Bias, per pixel**: the z-test of Mitsuba's own render regression tests
//!    ([`crate::study::metrics::z_test`]): z = |ours − ref| / √(var_ours/spp + var_ref/spp_ref) per
//!    pixel and channel, two-sided, Šidák-corrected α = [`ALPHA`] over all pixel-channels;
//!    passes when at least 99.75% of the pixel-channels pass.
//! 2. **Bias, global**: per channel, the image mean within [`MEAN_SIGMAS`] standard errors of
//!    the reference's (pixels are independent, so the standard error of a mean over N pixels
//!    is √(Σ var_i/spp)/N, for both images) and within [`MEAN_REL_TOL`] of it.
//! 3. **Convergence**: the least-squares slope of log RMSE against log spp over the steps
//!    above the reference's noise floor is −1/2 ± [`SLOPE_TOLERANCE`]
//!    ([`crate::study::convergence::fit_slope`]).

use crate::error::{Error, Result};
use crate::film::Filter;
use crate::io::exr::{self, RgbImage};
use crate::render::Job;
use crate::sampler::{Sampler, SamplerKind};
use crate::scene::Scene;
use crate::study::convergence::{
    fit_slope, reference_noise_floor, run_ladder, Ladder, LadderStep, SlopeFit, FLOOR_FACTOR,
    MIN_FIT_STEPS,
};
use crate::study::metrics::{channel_means, z_test, ZTest};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The scene list, relative to the repository root.
pub const SCENE_LIST: &str = "validation/scenes.toml";

/// Family-wise significance level of the per-pixel z-test (Šidák over pixel-channels).
pub const ALPHA: f64 = 0.01;

/// Check 2: the image mean may differ from the reference's by this many standard errors...
pub const MEAN_SIGMAS: f64 = 4.0;

/// ... and by this fraction of the reference's mean.
pub const MEAN_REL_TOL: f64 = 0.01;

/// Check 3: the fitted slope must be within this of −1/2.
pub const SLOPE_TOLERANCE: f64 = 0.1;

/// Whether a scene's feature is in penumbra yet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Landed,
    Pending,
}

/// One `[[scene]]` of the scene list.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValidationScene {
    pub name: String,
    /// Mitsuba XML, relative to the repository root.
    pub file: PathBuf,
    /// `$name` overrides, passed identically to Mitsuba and penumbra.
    #[serde(default)]
    pub defines: BTreeMap<String, String>,
    pub feature: String,
    pub status: Status,
    /// For pending scenes: what is missing.
    #[serde(default)]
    pub why: Option<String>,
    /// The Mitsuba reference EXR, relative to the repository root.
    pub reference: PathBuf,
    /// Samples per pixel of the reference.
    pub reference_spp: u32,
    /// Top of the tests' short ladder.
    pub test_spp: u32,
    /// Top of the study's ladder for this scene, when lower than `--max-spp` (large images).
    #[serde(default)]
    pub max_spp: Option<u32>,
    /// For the reference only: the integrator Mitsuba renders with instead of the scene's,
    /// as a `mi.load_dict` dictionary in JSON (render_all.py reads it). Used where Mitsuba
    /// 3.9.1 is wrong and an equivalent setting of its own is not, with the reason in
    /// `feature`.
    #[serde(default)]
    pub mitsuba_integrator: Option<String>,
    /// For the reference only: render_reference.py's `--variance` method, `passes` where
    /// Mitsuba's moment wrapper cannot take the integrator (its `ptracer`).
    #[serde(default)]
    pub mitsuba_variance: Option<String>,
    /// For penumbra only: the integrator it renders with instead of the scene's (a light
    /// path integrator, `ptracer`, checked against the scene's path-traced reference; it
    /// takes the scene integrator's max_depth, rr_depth and hide_emitters). Such an entry
    /// shares its reference with the scene's own entry.
    #[serde(default)]
    pub integrator: Option<String>,
    /// `"rgb"` (default) or `"spectral"`: the mode penumbra renders the entry in (`--mode`);
    /// a spectral entry's reference is rendered with Mitsuba's `llvm_ad_spectral`.
    #[serde(default)]
    pub mode: Option<String>,
    /// For the fast tests only: which checks they assert at `test_spp`, `"all"` (default),
    /// `"mean"` (the image mean only, for heavy-tailed scenes whose per-pixel z-test and
    /// slope cannot be resolved at the tests' sample counts: isolated fireflies in either
    /// renderer) or `"none"` (rendered and reported, nothing asserted: a scene whose image
    /// mean the tests' spp cannot estimate either), with the reason in `test_checks_why`.
    /// The study (`validate`) runs all three checks at its own spp.
    #[serde(default)]
    pub test_checks: Option<String>,
    #[serde(default)]
    pub test_checks_why: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneListFile {
    scene: Vec<ValidationScene>,
}

/// Reads and checks the scene list at `root`/[`SCENE_LIST`]: unique names, a reason for
/// every pending scene, positive sample counts.
pub fn load_scene_list(root: &Path) -> Result<Vec<ValidationScene>> {
    let path = root.join(SCENE_LIST);
    let text = std::fs::read_to_string(&path).map_err(|cause| Error::Io {
        path: path.clone(),
        cause,
    })?;
    parse_scene_list(&text).map_err(|e| Error::Invalid(format!("{}: {e}", path.display())))
}

/// Parses scene-list TOML text (see [`load_scene_list`]); errors are plain messages.
pub fn parse_scene_list(text: &str) -> std::result::Result<Vec<ValidationScene>, String> {
    let list: SceneListFile = toml::from_str(text).map_err(|e| e.to_string())?;
    let mut seen = std::collections::BTreeSet::new();
    for s in &list.scene {
        if !seen.insert(s.name.as_str()) {
            return Err(format!("scene '{}' is listed twice", s.name));
        }
        if s.name.is_empty() || s.name.contains(['/', '\\']) {
            return Err(format!("scene name '{}' must be a plain file stem", s.name));
        }
        if s.status == Status::Pending && s.why.as_deref().is_none_or(str::is_empty) {
            return Err(format!("pending scene '{}' needs a `why`", s.name));
        }
        match s.test_checks.as_deref() {
            None | Some("all") => {}
            Some("mean" | "none")
                if s.test_checks_why.as_deref().is_some_and(|w| !w.is_empty()) => {}
            Some(c @ ("mean" | "none")) => {
                return Err(format!(
                    "scene '{}': test_checks = \"{c}\" needs a `test_checks_why`",
                    s.name
                ))
            }
            Some(other) => {
                return Err(format!(
                    "scene '{}': test_checks must be \"all\", \"mean\" or \"none\", not '{other}'",
                    s.name
                ))
            }
        }
        if s.reference_spp == 0 || s.test_spp == 0 {
            return Err(format!(
                "scene '{}': reference_spp and test_spp must be positive",
                s.name
            ));
        }
    }
    Ok(list.scene)
}

/// A Mitsuba reference image with its per-sample variance.
#[derive(Clone, Debug)]
pub struct Reference {
    pub image: RgbImage,
    pub spp: u32,
    pub mitsuba_version: Option<String>,
    pub variant: Option<String>,
    pub render_seconds: Option<f64>,
}

impl Reference {
    /// Reads a reference EXR: R, G, B, variance.R/G/B and the `spp` header attribute that
    /// render_reference.py writes.
    pub fn read(path: &Path) -> Result<Reference> {
        let image = exr::read(path)?;
        let bad = |message: &str| Error::Image {
            path: path.to_path_buf(),
            message: message.to_string(),
        };
        if image.variance.is_none() {
            return Err(bad("reference has no variance.R/G/B channels"));
        }
        let spp = image
            .attributes
            .get("spp")
            .and_then(|s| s.trim().parse::<f64>().ok())
            .filter(|v| *v >= 1.0 && v.fract() == 0.0 && *v <= u32::MAX as f64)
            .ok_or_else(|| bad("reference has no positive integer `spp` header attribute"))?
            as u32;
        let attr = |k: &str| image.attributes.get(k).cloned();
        Ok(Reference {
            spp,
            mitsuba_version: attr("mitsuba_version"),
            variant: attr("mitsuba_variant"),
            render_seconds: attr("render_seconds").and_then(|s| s.parse().ok()),
            image,
        })
    }

    pub fn variance(&self) -> &[[f32; 3]] {
        self.image.variance.as_deref().unwrap_or(&[])
    }

    /// See [`reference_noise_floor`].
    pub fn noise_floor(&self) -> f64 {
        reference_noise_floor(self.variance(), self.spp as f64)
    }
}

impl ValidationScene {
    pub fn is_landed(&self) -> bool {
        self.status == Status::Landed
    }

    pub fn defines_vec(&self) -> Vec<(String, String)> {
        self.defines
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect()
    }

    /// `-D name=value ...` as both command lines take them.
    pub fn defines_args(&self) -> String {
        self.defines
            .iter()
            .map(|(k, v)| format!("-D {k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// The scene and its integrator (the list's, if it names one).
    pub fn load_job(&self, root: &Path) -> Result<Job> {
        let mut desc = Scene::load_description(&root.join(&self.file), &self.defines_vec())?;
        if let Some(kind) = &self.integrator {
            desc.use_integrator(kind)?;
        }
        desc.mode = self.render_mode()?;
        Job::build(&desc)
    }

    /// The entry's `mode` (RGB when absent).
    pub fn render_mode(&self) -> Result<crate::spectrum::Mode> {
        match self.mode.as_deref() {
            None => Ok(crate::spectrum::Mode::Rgb),
            Some(m) => crate::spectrum::Mode::from_name(m).ok_or_else(|| {
                Error::Invalid(format!("{}: mode '{m}' is not rgb or spectral", self.name))
            }),
        }
    }

    /// Reads the reference and checks that it is the one the list asks for.
    pub fn load_reference(&self, root: &Path) -> Result<Reference> {
        let path = root.join(&self.reference);
        let r = Reference::read(&path)?;
        if r.spp != self.reference_spp {
            return Err(Error::Image {
                path,
                message: format!(
                    "reference has {} spp, {} asks for {}: re-render it with \
                     validation/mitsuba/render_all.py",
                    r.spp, SCENE_LIST, self.reference_spp
                ),
            });
        }
        Ok(r)
    }
}

/// Check 2 for one channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelMean {
    pub ours: f64,
    pub reference: f64,
    /// Standard error of `ours − reference`.
    pub se: f64,
}

impl ChannelMean {
    pub fn diff(&self) -> f64 {
        self.ours - self.reference
    }

    /// |difference| in standard errors.
    pub fn sigmas(&self) -> f64 {
        self.diff().abs() / self.se
    }

    /// |difference| relative to the reference (infinite for a black reference channel that
    /// we do not match exactly).
    pub fn relative(&self) -> f64 {
        let d = self.diff().abs();
        if d == 0.0 {
            0.0
        } else {
            d / self.reference.abs()
        }
    }

    pub fn passed(&self) -> bool {
        let d = self.diff().abs();
        d <= MEAN_SIGMAS * self.se && d <= MEAN_REL_TOL * self.reference.abs()
    }
}

/// Check 2: per-channel image means.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanCheck {
    pub channels: [ChannelMean; 3],
}

impl MeanCheck {
    pub fn passed(&self) -> bool {
        self.channels.iter().all(ChannelMean::passed)
    }

    pub fn max_sigmas(&self) -> f64 {
        self.channels.iter().map(|c| c.sigmas()).fold(0.0, f64::max)
    }

    pub fn max_relative(&self) -> f64 {
        self.channels
            .iter()
            .map(|c| c.relative())
            .fold(0.0, f64::max)
    }
}

/// Check 2 on an image with its per-sample variance at `spp`, against `reference`, both
/// filtered by `filter`.
///
/// The standard error is that of the image mean, not of the pixels: a filter wider than a
/// pixel spreads each sample over several pixels, so neighbouring pixels are correlated and
/// summing their variances as if they were independent understates the mean's variance by
/// the filter's variance factor K (about 1/π for Mitsuba's default gaussian, 1/(4π) for a
/// gaussian of σ = 1 pixel). The image mean is, up to the edges, the plain mean of all
/// samples, so its variance is Σ σᵢ² / (spp n²) with σᵢ² = varᵢ / Kᵢ the per-sample variance
/// that pixel i's variance (its filtered estimate's, times spp) stands for; Kᵢ is
/// [`Filter::variance_factor_1d`] in x times in y (the reference's variance is scaled by the
/// same factor, validation/mitsuba/render_reference.py).
pub fn mean_check(
    rgb: &[[f32; 3]],
    variance: &[[f32; 3]],
    spp: f64,
    reference: &Reference,
    filter: Filter,
) -> MeanCheck {
    let (m_ours, m_ref) = (channel_means(rgb), channel_means(&reference.image.rgb));
    let n = rgb.len().max(1) as f64;
    let (w, h) = (reference.image.width, reference.image.height);
    let kx: Vec<f64> = (0..w).map(|x| filter.variance_factor_1d(x, w)).collect();
    let ky: Vec<f64> = (0..h).map(|y| filter.variance_factor_1d(y, h)).collect();
    let factor = |i: usize| {
        let k = kx.get(i % w.max(1)).copied().unwrap_or(1.0)
            * ky.get(i / w.max(1)).copied().unwrap_or(1.0);
        if k > 0.0 {
            k
        } else {
            1.0
        }
    };
    let var_of_mean = |v: &[[f32; 3]], spp: f64, c: usize| {
        v.iter()
            .enumerate()
            .map(|(i, p)| p[c] as f64 / factor(i))
            .sum::<f64>()
            / spp
            / (n * n)
    };
    let channels = std::array::from_fn(|c| ChannelMean {
        ours: m_ours[c],
        reference: m_ref[c],
        se: (var_of_mean(variance, spp, c)
            + var_of_mean(reference.variance(), reference.spp as f64, c))
        .sqrt(),
    });
    MeanCheck { channels }
}

/// Check 1 on an image with its per-sample variance at `spp`, against `reference`.
pub fn pixel_z_test(
    rgb: &[[f32; 3]],
    variance: &[[f32; 3]],
    spp: f64,
    reference: &Reference,
) -> Result<ZTest> {
    let r = &reference.image;
    if rgb.len() != r.rgb.len() || variance.len() != rgb.len() {
        return Err(Error::Invalid(format!(
            "image has {} pixels, the reference {}",
            rgb.len(),
            r.rgb.len()
        )));
    }
    let ours = RgbImage {
        width: r.width,
        height: r.height,
        rgb: rgb.to_vec(),
        variance: Some(variance.to_vec()),
        attributes: BTreeMap::new(),
    };
    z_test(&ours, spp, r, reference.spp as f64, ALPHA)
        .ok_or_else(|| Error::Invalid("z-test needs both variances".into()))
}

/// Everything measured for one scene.
#[derive(Clone, Debug)]
pub struct StudyResult {
    pub ladder: Ladder,
    /// Check 1, on the last step's image.
    pub z: ZTest,
    /// Check 2, on the last step's image.
    pub mean: MeanCheck,
    /// Check 3.
    pub slope: SlopeFit,
    /// The slopes check 3 accepts: −1/2 ± [`SLOPE_TOLERANCE`] for independent samples;
    /// for stratified and low-discrepancy samplers from −3/2 − tolerance (the best rate of
    /// scrambled nets on smooth integrands) to −1/2 + tolerance.
    pub slope_range: (f64, f64),
    /// Rendered with a stratified or low-discrepancy sampler.
    pub stratified: bool,
}

impl StudyResult {
    pub fn last(&self) -> Option<&LadderStep> {
        self.ladder.steps.last()
    }

    /// Check 3: enough steps above the floor and a slope within [`Self::slope_range`]. A
    /// stratified or low-discrepancy sampler may instead reach the reference's noise floor
    /// (the last step within [`FLOOR_FACTOR`] of it) before three steps could be fitted: a
    /// biased image would stay above it.
    pub fn slope_passed(&self) -> bool {
        let (lo, hi) = self.slope_range;
        let fitted = self.slope.used >= MIN_FIT_STEPS
            && self.slope.slope().is_some_and(|s| lo <= s && s <= hi);
        fitted || (self.stratified && self.slope.used < MIN_FIT_STEPS && self.reached_floor())
    }

    /// The last step's RMSE is within [`FLOOR_FACTOR`] of the reference's noise floor.
    pub fn reached_floor(&self) -> bool {
        self.last()
            .is_some_and(|st| st.metrics.rmse <= FLOOR_FACTOR * self.slope.floor)
    }

    /// The checks that failed, each with its numbers; empty when all pass.
    pub fn failures(&self) -> Vec<String> {
        let mut f = Vec::new();
        if !self.z.passed() {
            f.push(format!(
                "check 1 (per-pixel z-test): {} of {} pixel-channels have |z| > {:.2} \
                 (pass rate {:.4}%, need >= 99.75%); max |z| {:.2}",
                self.z.failures,
                self.z.tests,
                self.z.z_critical,
                100.0 * self.z.pass_rate(),
                self.z.z_max
            ));
        }
        for (c, m) in ["R", "G", "B"].iter().zip(&self.mean.channels) {
            if !m.passed() {
                f.push(format!(
                    "check 2 (image mean), channel {c}: {:.6} vs reference {:.6}: \
                     {:.2} standard errors (max {MEAN_SIGMAS}), {:.3}% (max {}%)",
                    m.ours,
                    m.reference,
                    m.sigmas(),
                    100.0 * m.relative(),
                    100.0 * MEAN_REL_TOL
                ));
            }
        }
        if !self.slope_passed() {
            f.push(match self.slope.slope() {
                Some(s) if self.slope.used >= MIN_FIT_STEPS => format!(
                    "check 3 (convergence): slope {s:.3} over {} steps, not in [{:.2}, {:.2}]",
                    self.slope.used, self.slope_range.0, self.slope_range.1
                ),
                _ => format!(
                    "check 3 (convergence): only {} of {} steps above {FLOOR_FACTOR}x the \
                     reference's noise floor {:.3e}; need {MIN_FIT_STEPS} (or, with a \
                     stratified sampler, the last step at the floor)",
                    self.slope.used, self.slope.total, self.slope.floor
                ),
            });
        }
        f
    }

    pub fn passed(&self) -> bool {
        self.failures().is_empty()
    }
}

/// Runs the ladder `steps` on `scene` and the three checks against `reference`.
pub fn study(
    job: &Job,
    reference: &Reference,
    steps: &[u32],
    seed: u64,
    threads: Option<usize>,
    on_step: &mut dyn FnMut(&LadderStep),
) -> Result<StudyResult> {
    let scene = &job.scene;
    if (scene.width, scene.height) != (reference.image.width, reference.image.height) {
        return Err(Error::Invalid(format!(
            "scene renders {}x{}, the reference is {}x{}",
            scene.width, scene.height, reference.image.width, reference.image.height
        )));
    }
    let ladder = run_ladder(job, steps, seed, threads, &reference.image.rgb, on_step)?;
    // the last step's own count (a sampler may have rounded it)
    let spp = ladder.steps.last().map_or(1, |st| st.spp) as f64;
    let (rgb, var) = (ladder.film.image(), ladder.film.sample_variance());
    let z = pixel_z_test(&rgb, &var, spp, reference)?;
    let mean = mean_check(&rgb, &var, spp, reference, scene.filter);
    let slope = fit_slope(&ladder.rmse_points(), reference.noise_floor(), FLOOR_FACTOR);
    let slope_range = if scene.sampler.kind == SamplerKind::Independent {
        (-0.5 - SLOPE_TOLERANCE, -0.5 + SLOPE_TOLERANCE)
    } else {
        (-1.5 - SLOPE_TOLERANCE, -0.5 + SLOPE_TOLERANCE)
    };
    Ok(StudyResult {
        ladder,
        z,
        mean,
        slope,
        slope_range,
        stratified: scene.sampler.kind != SamplerKind::Independent,
    })
}

/// A scene of the list, validated.
#[derive(Clone, Debug)]
pub struct SceneResult {
    pub scene: ValidationScene,
    pub reference: Reference,
    /// Scene loading and building, in seconds.
    pub load_seconds: f64,
    pub study: StudyResult,
}

/// Loads `entry`'s scene and reference from `root` and runs [`study`] up to `max_spp`.
/// With `sampler`, the scene's sampler is replaced by that plugin.
pub fn validate_scene(
    root: &Path,
    entry: &ValidationScene,
    steps: &[u32],
    seed: u64,
    threads: Option<usize>,
    sampler: Option<SamplerKind>,
    on_step: &mut dyn FnMut(&LadderStep),
) -> Result<SceneResult> {
    let t = Instant::now();
    let mut job = entry.load_job(root)?;
    if let Some(kind) = sampler {
        job.scene.sampler = Sampler::new(kind, job.scene.sample_count).0;
    }
    let load_seconds = t.elapsed().as_secs_f64();
    let reference = entry.load_reference(root)?;
    let study = study(&job, &reference, steps, seed, threads, on_step)?;
    Ok(SceneResult {
        scene: entry.clone(),
        reference,
        load_seconds,
        study,
    })
}

/// What the report says about how it was made.
#[derive(Clone, Debug, Default)]
pub struct ReportContext {
    pub command: String,
    /// UTC date and time.
    pub date: String,
    pub machine: String,
    pub penumbra_version: String,
    pub git_commit: Option<String>,
    pub seed: u64,
    /// Wall time of the whole study, in seconds.
    pub total_seconds: f64,
    /// Where the plots are, relative to the report's directory (`plots` in the repository).
    pub plots_dir: String,
}

fn status_cell(r: &StudyResult) -> String {
    let mut failed = Vec::new();
    if !r.z.passed() {
        failed.push("z-test");
    }
    if !r.mean.passed() {
        failed.push("mean");
    }
    if !r.slope_passed() {
        failed.push("slope");
    }
    if failed.is_empty() {
        "pass".into()
    } else {
        format!("**FAIL** ({})", failed.join(", "))
    }
}

fn slope_cell(r: &StudyResult) -> String {
    let s = &r.slope;
    let floor = if r.stratified && s.used < MIN_FIT_STEPS && r.reached_floor() {
        ", at the floor"
    } else {
        ""
    };
    match s.slope() {
        Some(v) => format!("{v:.3} ({}/{} steps{floor})", s.used, s.total),
        None => format!("n/a ({}/{} steps{floor})", s.used, s.total),
    }
}

/// The markdown report: a summary table over `results`, the pending scenes of `scenes`, and
/// per scene its reference, ladder, checks and plot (`<plots_dir>/<name>.png`).
pub fn report_markdown(
    results: &[SceneResult],
    scenes: &[ValidationScene],
    ctx: &ReportContext,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# penumbra vs. Mitsuba 3.9.1: validation report\n");
    let _ = writeln!(
        s,
        "Generated by `{}` on {} (UTC), {}; penumbra {}{}; seed {}; study wall time {:.1} s. \
         Do not edit by hand: rerun the command.\n",
        ctx.command,
        ctx.date,
        ctx.machine,
        ctx.penumbra_version,
        ctx.git_commit
            .as_deref()
            .map(|c| format!(" (commit {c})"))
            .unwrap_or_default(),
        ctx.seed,
        ctx.total_seconds
    );
    let _ = writeln!(
        s,
        "Checks, on the last (highest-spp) image of each ladder, against the Mitsuba reference:\n\n\
         1. **z-test**: z = \\|ours − ref\\| / √(var_ours/spp + var_ref/spp_ref) per pixel and \
         channel (per-sample variances floored at 1e-4), two-sided, Šidák-corrected α = {ALPHA} \
         over all pixel-channels; passes when ≥ 99.75% pass.\n\
         2. **mean**: per channel, the image mean within {MEAN_SIGMAS} standard errors and \
         within {}% of the reference's (se: standard error of the difference of the means). The \
         column shows the worst channel.\n\
         3. **slope**: least-squares slope of ln RMSE vs. ln spp over the ladder \
         (1, 4, 16, ... spp, each step continuing the previous one's samples), −0.5 ± \
         {SLOPE_TOLERANCE} (with a stratified or low-discrepancy sampler: between −1.5 − \
         {SLOPE_TOLERANCE} and −0.5 + {SLOPE_TOLERANCE}, each step a render of its own). The fit stops at the first step whose RMSE is within \
         {FLOOR_FACTOR}× the reference's noise floor √(mean(var_ref)/spp_ref) (the RMSE a \
         perfect image would show); at least {MIN_FIT_STEPS} steps are needed.\n\n\
         RMSE and relative MSE (mean of (ours − ref)² / (ref² + 0.01)) are over all \
         pixel-channels. Times are penumbra's sampling wall time (scene loading excluded) on \
         a machine shared with other jobs.\n",
        100.0 * MEAN_REL_TOL
    );
    let _ = writeln!(s, "## Summary\n");
    let _ = writeln!(
        s,
        "| scene | spp | time (s) | RMSE | rel. MSE | z-test pass | mean Δ (worst channel) | slope | status |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---|");
    for r in results {
        let st = &r.study;
        let Some(last) = st.last() else { continue };
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {:.3e} | {:.3e} | {:.3}% | {:.2} se, {:.3}% | {} | {} |",
            r.scene.name,
            last.spp,
            last.seconds,
            last.metrics.rmse,
            last.metrics.rel_mse,
            100.0 * st.z.pass_rate(),
            st.mean.max_sigmas(),
            100.0 * st.mean.max_relative(),
            slope_cell(st),
            status_cell(st)
        );
    }
    let pending: Vec<_> = scenes.iter().filter(|s| !s.is_landed()).collect();
    if !pending.is_empty() {
        let _ = writeln!(s, "\n## Pending scenes\n");
        let _ = writeln!(
            s,
            "Listed in `{SCENE_LIST}`, not validated until their feature lands.\n"
        );
        let _ = writeln!(s, "| scene | feature | why pending |");
        let _ = writeln!(s, "|---|---|---|");
        for p in pending {
            let _ = writeln!(
                s,
                "| {} | {} | {} |",
                p.name,
                p.feature,
                p.why.as_deref().unwrap_or("")
            );
        }
    }
    for r in results {
        write_scene_section(&mut s, r, &ctx.plots_dir);
    }
    s
}

fn write_scene_section(s: &mut String, r: &SceneResult, plots_dir: &str) {
    let e = &r.scene;
    let st = &r.study;
    let refr = &r.reference;
    let _ = writeln!(s, "\n## {}\n", e.name);
    let _ = writeln!(s, "{}.\n", e.feature);
    let defines = e.defines_args();
    let _ = writeln!(
        s,
        "- scene: `{}`{}",
        e.file.display(),
        if defines.is_empty() {
            String::new()
        } else {
            format!(" with `{defines}`")
        }
    );
    let (w, h) = (refr.image.width, refr.image.height);
    let mitsuba_rate = refr
        .render_seconds
        .map(|t| {
            format!(
                ", {:.2} Mpath/s",
                (w * h) as f64 * refr.spp as f64 / t / 1e6
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        s,
        "- reference: `{}`, {}x{}, {} spp, Mitsuba {} `{}`{}{}",
        e.reference.display(),
        w,
        h,
        refr.spp,
        refr.mitsuba_version.as_deref().unwrap_or("?"),
        refr.variant.as_deref().unwrap_or("?"),
        refr.render_seconds
            .map(|t| format!(", {t:.1} s"))
            .unwrap_or_default(),
        mitsuba_rate
    );
    let stats = &st.ladder.stats;
    let _ = writeln!(
        s,
        "- penumbra: scene load {:.1} ms, {:.2} Mpath/s over the ladder, {} non-finite samples",
        1e3 * r.load_seconds,
        stats.mpaths_per_second(),
        stats.nonfinite
    );
    let _ = writeln!(
        s,
        "- mean per-sample variance over pixel-channels: penumbra {:.4e}, Mitsuba {:.4e}; \
         reference noise floor \
         √(mean(var_ref)/spp_ref) = {:.3e}\n",
        st.ladder.mean_sample_variance(),
        crate::study::convergence::mean_of(refr.variance()),
        st.slope.floor
    );
    let _ = writeln!(
        s,
        "| spp | time (s) | RMSE | rel. MSE | RMSE / floor | in fit |"
    );
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---|");
    for (i, step) in st.ladder.steps.iter().enumerate() {
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.4e} | {:.4e} | {:.1} | {} |",
            step.spp,
            step.seconds,
            step.metrics.rmse,
            step.metrics.rel_mse,
            step.metrics.rmse / st.slope.floor,
            if i < st.slope.used { "yes" } else { "no" }
        );
    }
    let _ = writeln!(
        s,
        "\nz-test: {} of {} pixel-channels above |z| = {:.3} (pass rate {:.4}%), max |z| {:.2}.\n",
        st.z.failures,
        st.z.tests,
        st.z.z_critical,
        100.0 * st.z.pass_rate(),
        st.z.z_max
    );
    let _ = writeln!(
        s,
        "| channel | penumbra mean | Mitsuba mean | Δ | Δ / se | Δ / ref |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
    for (c, m) in ["R", "G", "B"].iter().zip(&st.mean.channels) {
        let _ = writeln!(
            s,
            "| {c} | {:.6} | {:.6} | {:+.2e} | {:.2} | {:.4}% |",
            m.ours,
            m.reference,
            m.diff(),
            m.sigmas(),
            100.0 * m.relative()
        );
    }
    let failures = st.failures();
    if failures.is_empty() {
        let _ = writeln!(s, "\nAll checks pass.");
    } else {
        let _ = writeln!(s);
        for f in failures {
            let _ = writeln!(s, "- **{f}**");
        }
    }
    let _ = writeln!(s, "\n![{0} convergence]({plots_dir}/{0}.png)", e.name);
}
