//! Convergence experiments (`penumbra converge`): a scene rendered along a ladder of sample
//! counts ([`crate::study::convergence::run_ladder_with_film`], each step continuing the previous
//! one's samples) against a reference image, for K seeds and for each value of one swept scene
//! parameter. Per step: wall time, Mpath/s, every error metric of [`crate::study::metrics`], the
//! per-pixel z-test pass rate ([`crate::study::compare::z_test_either`]) and the efficiency
//! 1 / (time × MSE); per ladder, the fitted slope of log RMSE against log spp
//! ([`crate::study::convergence::fit_slope`]); over seeds, the mean and spread. Written as CSV, JSON
//! and a plot ([`crate::study::plot::write_series_png`]).

use crate::error::{Error, Result};
use crate::film::Film;
use crate::io::exr::RgbImage;
use crate::render::Job;
use crate::render::RenderStats;
use crate::sampler::SamplerKind;
use crate::scene::description::{IntegratorDesc, SceneDescription};
use crate::scene::Scene;
use crate::study::compare::z_test_either;
use crate::study::convergence::{fit_slope, mean_of, reference_noise_floor, run_ladder_with_film};
use crate::study::convergence::{SlopeFit, FLOOR_FACTOR};
use crate::study::metrics::ErrorMetrics;
use crate::study::plot::{Series, SeriesPoint};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// The default ladder: 1, 2, 4, ..., 4096 spp.
pub const DEFAULT_SPP: &str = "1,2,4,...,4096";

/// The z-test is reported from this many samples per pixel on: below it the per-pixel
/// variance estimates are too noisy (at 1 spp they are 0) for the test to mean anything.
pub const MIN_SPP_FOR_Z_TEST: u32 = 16;

/// Parses a ladder of samples per pixel: positive integers separated by commas, strictly
/// increasing. `a,b,...,n` continues the geometric progression of ratio b/a (an integer of
/// at least 2) up to n, ending with n itself: `1,2,4,...,4096`, `1,4,...,1000` (1, 4, 16, 64,
/// 256, 1000).
pub fn parse_spp_list(text: &str) -> std::result::Result<Vec<u32>, String> {
    let bad = |why: String| format!("bad --spp list '{text}': {why}");
    let tokens: Vec<&str> = text.split(',').map(str::trim).collect();
    let mut steps: Vec<u32> = Vec::new();
    let mut i = 0;
    while i < tokens.len() {
        let t = tokens[i];
        if t == "..." || t == "…" {
            let n = steps.len();
            if n < 2 {
                return Err(bad("'...' needs two values before it".into()));
            }
            let end = tokens
                .get(i + 1)
                .ok_or_else(|| bad("'...' needs a last value after it".into()))?;
            let end: u32 = end
                .parse()
                .map_err(|_| bad(format!("'{end}' is not a positive integer")))?;
            let (a, b) = (steps[n - 2], steps[n - 1]);
            if b % a != 0 || b / a < 2 {
                return Err(bad(format!(
                    "'...' continues a progression of integer ratio >= 2, not {a}, {b}"
                )));
            }
            let ratio = b / a;
            let mut v = b;
            while let Some(next) = v.checked_mul(ratio).filter(|&x| x < end) {
                steps.push(next);
                v = next;
            }
            steps.push(end);
            i += 2;
            continue;
        }
        let v: u32 = t
            .parse()
            .map_err(|_| bad(format!("'{t}' is not a positive integer")))?;
        steps.push(v);
        i += 1;
    }
    if steps.first() == Some(&0) || steps.contains(&0) {
        return Err(bad("sample counts must be at least 1".into()));
    }
    if let Some(w) = steps.windows(2).find(|w| w[1] <= w[0]) {
        return Err(bad(format!(
            "sample counts must increase strictly ({} then {})",
            w[0], w[1]
        )));
    }
    if steps.len() < 2 {
        return Err(bad("a ladder needs at least two steps".into()));
    }
    Ok(steps)
}

/// A swept parameter: `NAME=v1,v2,...` (at least two distinct values).
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    pub name: String,
    pub values: Vec<String>,
}

impl Sweep {
    pub fn parse(text: &str) -> std::result::Result<Sweep, String> {
        let bad = |why: &str| format!("bad --sweep '{text}': {why} (expected NAME=v1,v2,...)");
        let (name, values) = text.split_once('=').ok_or_else(|| bad("no '='"))?;
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty parameter name"));
        }
        let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
        if values.iter().any(String::is_empty) {
            return Err(bad("empty value"));
        }
        let mut seen = std::collections::BTreeSet::new();
        if let Some(v) = values.iter().find(|v| !seen.insert(v.as_str())) {
            return Err(bad(&format!("value '{v}' is given twice")));
        }
        if values.len() < 2 {
            return Err(bad("a sweep needs at least two values"));
        }
        Ok(Sweep {
            name: name.to_string(),
            values,
        })
    }
}

/// How a swept value reaches the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SweepMode {
    /// As `-D NAME=value` (the scene declares `<default name="NAME">` and uses `$NAME`).
    Define,
    /// Set on the path integrator directly (`max_depth`, `rr_depth`), because the scene
    /// does not use `$NAME`.
    Integrator,
    /// `sampler=NAME,...`: the scene's sampler replaced by each plugin (same sample_count
    /// and seed), unless the scene declares `<default name="sampler">` itself.
    Sampler,
    /// `integrator=NAME,...`: the scene's integrator switched to each plugin as `penumbra
    /// render --integrator` does (its max_depth, rr_depth and hide_emitters kept), unless
    /// the scene declares `<default name="integrator">` itself.
    SwitchIntegrator,
}

/// One scene of an experiment: the whole scene, or one value of the sweep.
#[derive(Clone, Debug)]
pub struct Variant {
    /// `NAME=value`, or empty without a sweep.
    pub label: String,
    pub value: Option<String>,
    pub description: SceneDescription,
}

/// Parameters that `--sweep` may set on the path integrator when the scene does not declare
/// them as `<default>`s.
pub const INTEGRATOR_PARAMETERS: [&str; 2] = ["max_depth", "rr_depth"];

fn set_integrator_parameter(desc: &mut SceneDescription, name: &str, value: &str) -> Result<()> {
    let v: i64 = value.parse().map_err(|_| {
        Error::Invalid(format!(
            "--sweep {name}: '{value}' is not an integer (the path integrator's {name})"
        ))
    })?;
    #[allow(unreachable_patterns)]
    match &mut desc.integrator {
        IntegratorDesc::Path {
            max_depth,
            rr_depth,
            ..
        } => {
            if name == "max_depth" {
                if v < -1 {
                    return Err(Error::Invalid(format!(
                        "--sweep max_depth: must be -1 (unbounded) or >= 0, got {v}"
                    )));
                }
                *max_depth = v;
            } else {
                if v <= 0 {
                    return Err(Error::Invalid(format!(
                        "--sweep rr_depth: must be > 0, got {v}"
                    )));
                }
                *rr_depth = v;
            }
            Ok(())
        }
        _ => Err(Error::Invalid(format!(
            "--sweep {name}: the scene's integrator has no {name}"
        ))),
    }
}

/// The scene descriptions of an experiment: `defines` applied to the file at `path`, and for
/// each value of `sweep` its variant. A swept name the scene uses as `$NAME` is passed like
/// `-D NAME=value`; if no value changes the scene (no `<default name="NAME">` is used) and
/// NAME is `max_depth` or `rr_depth`, it is set on the path integrator directly; `sampler`
/// and `integrator` replace the scene's sampler or switch its integrator; otherwise the
/// sweep is refused (it would draw identical curves).
pub fn scene_variants(
    path: &Path,
    defines: &[(String, String)],
    sweep: Option<&Sweep>,
) -> Result<(Vec<Variant>, Option<SweepMode>)> {
    let base = Scene::load_description(path, defines)?;
    let Some(sweep) = sweep else {
        return Ok((
            vec![Variant {
                label: String::new(),
                value: None,
                description: base,
            }],
            None,
        ));
    };
    if defines.iter().any(|(k, _)| k == &sweep.name) {
        return Err(Error::Invalid(format!(
            "{} is both swept (--sweep) and fixed (-D)",
            sweep.name
        )));
    }
    let mut variants = Vec::with_capacity(sweep.values.len());
    for v in &sweep.values {
        let mut d = defines.to_vec();
        d.push((sweep.name.clone(), v.clone()));
        variants.push(Variant {
            label: format!("{}={v}", sweep.name),
            value: Some(v.clone()),
            description: Scene::load_description(path, &d)?,
        });
    }
    // (Warnings are not the scene: an override the file does not use is warned about.)
    let same_scene = |a: &SceneDescription, b: &SceneDescription| {
        let (mut a, mut b) = (a.clone(), b.clone());
        a.warnings.clear();
        b.warnings.clear();
        a == b
    };
    if variants.iter().any(|v| !same_scene(&v.description, &base)) {
        return Ok((variants, Some(SweepMode::Define)));
    }
    if sweep.name == "sampler" {
        for v in &mut variants {
            let value = v.value.clone().unwrap_or_default();
            v.description.sensor.sampler.kind =
                SamplerKind::from_name(&value).ok_or_else(|| {
                    Error::Invalid(format!(
                        "--sweep sampler: unknown sampler '{value}' (independent, stratified, \
                         multijitter, orthogonal, ldsampler, zsobol)"
                    ))
                })?;
        }
        return Ok((variants, Some(SweepMode::Sampler)));
    }
    if sweep.name == "integrator" {
        for v in &mut variants {
            let value = v.value.clone().unwrap_or_default();
            // The file as loaded without the swept name (which it does not use: no warning).
            v.description = base.clone();
            v.description.integrator = base.integrator.switched_to(&value)?;
        }
        return Ok((variants, Some(SweepMode::SwitchIntegrator)));
    }
    if !INTEGRATOR_PARAMETERS.contains(&sweep.name.as_str()) {
        return Err(Error::Invalid(format!(
            "--sweep {0}: no value changes the scene ({1} does not use ${0}); sweep a \
             parameter declared with <default name=\"{0}\">, the path integrator's \
             max_depth or rr_depth, the sampler or the integrator",
            sweep.name,
            path.display()
        )));
    }
    for v in &mut variants {
        let value = v.value.clone().unwrap_or_default();
        set_integrator_parameter(&mut v.description, &sweep.name, &value)?;
    }
    Ok((variants, Some(SweepMode::Integrator)))
}

/// The reference an experiment measures against.
#[derive(Clone, Debug)]
pub struct ReferenceImage {
    pub image: RgbImage,
    /// Its samples per pixel (header attribute `spp`, or given), for the z-test and the
    /// noise floor.
    pub spp: Option<f64>,
}

impl ReferenceImage {
    /// The RMSE a perfect image would show against this reference
    /// ([`reference_noise_floor`]); `None` without variance channels or spp.
    pub fn noise_floor(&self) -> Option<f64> {
        let var = self.image.variance.as_ref()?;
        Some(reference_noise_floor(var, self.spp?))
    }
}

/// One step of one ladder.
#[derive(Clone, Debug)]
pub struct StepRecord {
    pub spp: u32,
    /// Sampling wall time so far, in seconds.
    pub seconds: f64,
    /// Camera paths per second so far, in millions.
    pub mpaths_per_second: f64,
    pub metrics: ErrorMetrics,
    /// Pass rate of the per-pixel z-test (from [`MIN_SPP_FOR_Z_TEST`] spp on, when a
    /// variance and the reference's spp are known).
    pub z_pass_rate: Option<f64>,
    /// 1 / (seconds × MSE).
    pub efficiency: f64,
}

/// One ladder: one variant, one seed.
#[derive(Clone, Debug)]
pub struct Run {
    pub seed: u64,
    pub steps: Vec<StepRecord>,
    pub slope: SlopeFit,
    /// Mean per-sample variance of the final image (σ² of the ideal curve σ/√spp).
    pub mean_sample_variance: f64,
    pub stats: RenderStats,
}

/// 1 / (seconds × MSE): how much error a second of rendering removes. Two settings reach the
/// same MSE in times inversely proportional to their efficiencies.
pub fn efficiency(seconds: f64, mse: f64) -> f64 {
    1.0 / (seconds * mse)
}

/// Renders the ladder `steps` of `job` with `seed` against `reference` (same resolution).
/// With `max_seconds`, the ladder stops after the first step whose time reaches it.
/// `on_step` sees each step's record and its film (the image so far).
pub fn run_one(
    job: &Job,
    steps: &[u32],
    seed: u64,
    threads: Option<usize>,
    reference: &ReferenceImage,
    max_seconds: Option<f64>,
    on_step: &mut dyn FnMut(&StepRecord, &Film),
) -> Result<Run> {
    let scene = &job.scene;
    let r = &reference.image;
    if (scene.width, scene.height) != (r.width, r.height) {
        return Err(Error::Invalid(format!(
            "the scene renders {}x{}, the reference is {}x{} (set the scene's resolution with \
             -D, e.g. -D res={})",
            scene.width, scene.height, r.width, r.height, r.width
        )));
    }
    let pixels = (scene.width * scene.height) as f64;
    let mut records = Vec::with_capacity(steps.len());
    let ladder = run_ladder_with_film(
        job,
        steps,
        seed,
        threads,
        &r.rgb,
        max_seconds,
        &mut |step, film| {
            let z_pass_rate = (step.spp >= MIN_SPP_FOR_Z_TEST)
                .then(|| {
                    let ours = RgbImage {
                        width: film.width,
                        height: film.height,
                        rgb: film.image(),
                        variance: Some(film.sample_variance()),
                        attributes: BTreeMap::new(),
                    };
                    let z = z_test_either(
                        &ours,
                        Some(step.spp as f64),
                        r,
                        reference.spp,
                        crate::study::validation::ALPHA,
                    );
                    z.test().map(|t| t.pass_rate())
                })
                .flatten();
            let record = StepRecord {
                spp: step.spp,
                seconds: step.seconds,
                mpaths_per_second: pixels * step.spp as f64 / step.seconds.max(1e-9) / 1e6,
                efficiency: efficiency(step.seconds, step.metrics.mse),
                metrics: step.metrics.clone(),
                z_pass_rate,
            };
            on_step(&record, film);
            records.push(record);
        },
    )?;
    let points: Vec<(f64, f64)> = ladder.rmse_points();
    let slope = fit_slope(
        &points,
        reference.noise_floor().unwrap_or(0.0),
        FLOOR_FACTOR,
    );
    Ok(Run {
        seed,
        steps: records,
        slope,
        mean_sample_variance: mean_of(&ladder.film.sample_variance()),
        stats: ladder.stats,
    })
}

/// Mean, sample standard deviation (with at least two values), minimum and maximum.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Spread {
    pub mean: f64,
    pub std: Option<f64>,
    pub min: f64,
    pub max: f64,
}

/// The [`Spread`] of `values` (`None` if empty).
pub fn spread(values: &[f64]) -> Option<Spread> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let std = (values.len() >= 2)
        .then(|| (values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)).sqrt());
    Some(Spread {
        mean,
        std,
        min: values.iter().copied().fold(f64::INFINITY, f64::min),
        max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    })
}

/// One step summarised over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct StepSummary {
    pub spp: u32,
    pub seconds: Spread,
    pub mpaths_per_second: Spread,
    pub rmse: Spread,
    pub rel_mse: Spread,
    pub mae: Spread,
    pub efficiency: Spread,
    pub z_pass_rate: Option<Spread>,
}

/// All ladders of one variant.
#[derive(Clone, Debug)]
pub struct SeriesResult {
    /// `NAME=value`, or empty without a sweep.
    pub label: String,
    pub value: Option<String>,
    pub runs: Vec<Run>,
}

impl SeriesResult {
    /// Per step, the spread over seeds (all runs share the ladder).
    pub fn summary(&self) -> Vec<StepSummary> {
        let Some(first) = self.runs.first() else {
            return Vec::new();
        };
        (0..first.steps.len())
            .filter_map(|i| {
                let steps: Vec<&StepRecord> =
                    self.runs.iter().filter_map(|r| r.steps.get(i)).collect();
                let of = |f: &dyn Fn(&StepRecord) -> f64| {
                    spread(&steps.iter().map(|s| f(s)).collect::<Vec<_>>())
                };
                let z: Vec<f64> = steps.iter().filter_map(|s| s.z_pass_rate).collect();
                Some(StepSummary {
                    spp: first.steps[i].spp,
                    seconds: of(&|s| s.seconds)?,
                    mpaths_per_second: of(&|s| s.mpaths_per_second)?,
                    rmse: of(&|s| s.metrics.rmse)?,
                    rel_mse: of(&|s| s.metrics.rel_mse)?,
                    mae: of(&|s| s.metrics.mae)?,
                    efficiency: of(&|s| s.efficiency)?,
                    z_pass_rate: if z.len() == steps.len() {
                        spread(&z)
                    } else {
                        None
                    },
                })
            })
            .collect()
    }

    /// The fitted slopes' spread over seeds (runs whose fit had two steps or more).
    pub fn slope_spread(&self) -> Option<Spread> {
        spread(
            &self
                .runs
                .iter()
                .filter_map(|r| r.slope.slope())
                .collect::<Vec<_>>(),
        )
    }

    /// The series drawn in the plot: mean RMSE and time over seeds, whiskers from min to
    /// max RMSE.
    pub fn plot_series(&self) -> Series {
        let slope = match self.slope_spread() {
            Some(s) if self.runs.len() > 1 => {
                format!("slope {:.3} ± {:.3}", s.mean, s.std.unwrap_or(0.0))
            }
            Some(s) => format!("slope {:.3}", s.mean),
            None => "slope n/a".into(),
        };
        let name = if self.label.is_empty() {
            "penumbra".to_string()
        } else {
            self.label.clone()
        };
        Series {
            label: format!("{name}: {slope}"),
            points: self
                .summary()
                .iter()
                .map(|s| SeriesPoint {
                    spp: s.spp as f64,
                    seconds: s.seconds.mean,
                    rmse: s.rmse.mean,
                    rmse_min: s.rmse.min,
                    rmse_max: s.rmse.max,
                })
                .collect(),
            sample_variance: spread(
                &self
                    .runs
                    .iter()
                    .map(|r| r.mean_sample_variance)
                    .collect::<Vec<_>>(),
            )
            .map_or(0.0, |s| s.mean),
        }
    }
}

/// Formats a number for CSV: shortest round-trip form, empty for `None`, `nan`/`inf` as is.
fn csv_num(v: Option<f64>) -> String {
    v.map(|x| format!("{x}")).unwrap_or_default()
}

/// The CSV header of [`to_csv`].
pub const CSV_HEADER: &str = "param,value,seed,spp,seconds,mpaths_per_s,rmse,mse,rel_mse,mae,\
                              max_abs,mean_r,mean_g,mean_b,nonfinite,z_pass_rate,efficiency";

/// One row per step, per seed, per variant.
pub fn to_csv(param: Option<&str>, results: &[SeriesResult]) -> String {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in results {
        for run in &r.runs {
            for st in &run.steps {
                let m = &st.metrics;
                let _ = writeln!(
                    s,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    param.unwrap_or(""),
                    r.value.as_deref().unwrap_or(""),
                    run.seed,
                    st.spp,
                    st.seconds,
                    st.mpaths_per_second,
                    m.rmse,
                    m.mse,
                    m.rel_mse,
                    m.mae,
                    m.max_abs,
                    m.mean_a[0],
                    m.mean_a[1],
                    m.mean_a[2],
                    m.nonfinite,
                    csv_num(st.z_pass_rate),
                    st.efficiency
                );
            }
        }
    }
    s
}

/// What `converge.json` says about the experiment.
#[derive(Clone, Debug, Serialize)]
pub struct ExperimentInfo {
    pub scene: String,
    pub reference: String,
    pub reference_spp: Option<f64>,
    /// Whether the reference has variance channels.
    pub reference_variance: bool,
    pub noise_floor: Option<f64>,
    pub width: usize,
    pub height: usize,
    pub defines: BTreeMap<String, String>,
    pub sweep: Option<SweepInfo>,
    pub seeds: Vec<u64>,
    pub spp: Vec<u32>,
    pub threads: Option<usize>,
    pub penumbra_version: String,
    pub command: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct SweepInfo {
    pub param: String,
    pub values: Vec<String>,
    /// `define` (-D NAME=value) or `integrator` (set on the path integrator).
    pub mode: String,
}

#[derive(Serialize)]
struct StepJson {
    spp: u32,
    seconds: f64,
    mpaths_per_second: f64,
    rmse: f64,
    mse: f64,
    rel_mse: f64,
    mae: f64,
    max_abs: f64,
    mean: [f64; 3],
    nonfinite: usize,
    z_pass_rate: Option<f64>,
    efficiency: f64,
}

#[derive(Serialize)]
struct RunJson {
    seed: u64,
    slope: Option<f64>,
    slope_steps_used: usize,
    mean_sample_variance: f64,
    nonfinite_samples: u64,
    steps: Vec<StepJson>,
}

#[derive(Serialize)]
struct SeriesJson {
    label: String,
    value: Option<String>,
    slope: Option<Spread>,
    summary: Vec<StepSummary>,
    runs: Vec<RunJson>,
}

#[derive(Serialize)]
struct ExperimentJson<'a> {
    #[serde(flatten)]
    info: &'a ExperimentInfo,
    /// The slope fit's rule: steps until the RMSE comes within this factor of the floor.
    floor_factor: f64,
    series: Vec<SeriesJson>,
}

/// `converge.json`: the experiment, then per variant the summary over seeds and every run's
/// steps. Non-finite numbers are written as null.
pub fn to_json(info: &ExperimentInfo, results: &[SeriesResult]) -> Result<String> {
    let series = results
        .iter()
        .map(|r| SeriesJson {
            label: r.label.clone(),
            value: r.value.clone(),
            slope: r.slope_spread(),
            summary: r.summary(),
            runs: r
                .runs
                .iter()
                .map(|run| RunJson {
                    seed: run.seed,
                    slope: run.slope.slope(),
                    slope_steps_used: run.slope.used,
                    mean_sample_variance: run.mean_sample_variance,
                    nonfinite_samples: run.stats.nonfinite,
                    steps: run
                        .steps
                        .iter()
                        .map(|s| StepJson {
                            spp: s.spp,
                            seconds: s.seconds,
                            mpaths_per_second: s.mpaths_per_second,
                            rmse: s.metrics.rmse,
                            mse: s.metrics.mse,
                            rel_mse: s.metrics.rel_mse,
                            mae: s.metrics.mae,
                            max_abs: s.metrics.max_abs,
                            mean: s.metrics.mean_a,
                            nonfinite: s.metrics.nonfinite,
                            z_pass_rate: s.z_pass_rate,
                            efficiency: s.efficiency,
                        })
                        .collect(),
                })
                .collect(),
        })
        .collect();
    let mut text = serde_json::to_string_pretty(&ExperimentJson {
        info,
        floor_factor: FLOOR_FACTOR,
        series,
    })
    .map_err(|e| Error::Invalid(format!("cannot encode JSON: {e}")))?;
    text.push('\n');
    Ok(text)
}

fn spread_cell(s: &Spread, fmt: impl Fn(f64) -> String) -> String {
    match s.std {
        Some(sd) => format!(
            "{} ± {} [{}, {}]",
            fmt(s.mean),
            fmt(sd),
            fmt(s.min),
            fmt(s.max)
        ),
        None => fmt(s.mean),
    }
}

/// The per-step table of one variant, as markdown: spp, time, Mpath/s, RMSE, relative MSE,
/// efficiency, z-test pass rate (means over seeds; with several seeds RMSE shows
/// mean ± standard deviation [min, max]), then the slope.
pub fn table(r: &SeriesResult) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| spp | time (s) | Mpath/s | RMSE | rel. MSE | efficiency 1/(s·MSE) | z-test pass |"
    );
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|");
    for st in r.summary() {
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.3} | {} | {:.4e} | {:.4e} | {} |",
            st.spp,
            st.seconds.mean,
            st.mpaths_per_second.mean,
            spread_cell(&st.rmse, |v| format!("{v:.4e}")),
            st.rel_mse.mean,
            st.efficiency.mean,
            st.z_pass_rate
                .map_or("–".into(), |z| format!("{:.3}%", 100.0 * z.mean))
        );
    }
    let used = r.runs.first().map_or(0, |run| run.slope.used);
    let total = r.runs.first().map_or(0, |run| run.slope.total);
    match r.slope_spread() {
        Some(sl) => {
            let _ = writeln!(
                s,
                "\nslope of log RMSE vs. log spp: {} (fit over {used} of {total} steps{})",
                spread_cell(&sl, |v| format!("{v:.3}")),
                r.runs
                    .first()
                    .filter(|run| run.slope.floor > 0.0)
                    .map(|run| format!(
                        ", those above {FLOOR_FACTOR}× the reference noise floor {:.3e}",
                        run.slope.floor
                    ))
                    .unwrap_or_default()
            );
        }
        None => {
            let _ = writeln!(
                s,
                "\nslope: n/a (only {used} of {total} steps above the fit's floor)"
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spp_lists() {
        assert_eq!(
            parse_spp_list("1,2,4,...,4096").unwrap(),
            (0..=12).map(|k| 1u32 << k).collect::<Vec<_>>()
        );
        assert_eq!(
            parse_spp_list("1,4,...,1000").unwrap(),
            vec![1, 4, 16, 64, 256, 1000]
        );
        assert_eq!(parse_spp_list(" 3, 5 ,8").unwrap(), vec![3, 5, 8]);
        assert_eq!(parse_spp_list("2,4,...,16").unwrap(), vec![2, 4, 8, 16]);
        for bad in [
            "",
            "1",
            "4,2",
            "1,1",
            "0,1",
            "1,x",
            "1,...,8",
            "2,3,...,9",
            "1,2,...",
            "1,-2",
        ] {
            assert!(parse_spp_list(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn sweeps() {
        let s = Sweep::parse("max_depth=2, 4,8").unwrap();
        assert_eq!(s.name, "max_depth");
        assert_eq!(s.values, vec!["2", "4", "8"]);
        for bad in ["max_depth", "=1,2", "max_depth=2", "a=1,,2", "a=1,1"] {
            assert!(Sweep::parse(bad).is_err(), "{bad}");
        }
    }

    fn base_warnings(file: &Path) -> Vec<String> {
        Scene::load_description(file, &[]).unwrap().warnings
    }

    /// `integrator=...` on a scene that names its integrator (the Cornell box's `path`,
    /// max_depth 8) switches it, keeping max_depth, without a warning about an unused
    /// $integrator; an unknown one is refused.
    #[test]
    fn an_integrator_sweep_switches_the_scenes_integrator() {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.xml");
        let sweep = Sweep::parse("integrator=path,bdpt").unwrap();
        let (v, mode) = scene_variants(&file, &[], Some(&sweep)).unwrap();
        assert_eq!(mode, Some(SweepMode::SwitchIntegrator));
        assert!(matches!(
            v[0].description.integrator,
            IntegratorDesc::Path { max_depth: 8, .. }
        ));
        assert!(matches!(
            v[1].description.integrator,
            IntegratorDesc::Bdpt { max_depth: 8, .. }
        ));
        assert!(v
            .iter()
            .all(|v| v.description.warnings == base_warnings(&file)));
        let bad = Sweep::parse("integrator=path,nope").unwrap();
        assert!(scene_variants(&file, &[], Some(&bad)).is_err());
    }

    #[test]
    fn spread_values() {
        let s = spread(&[1.0, 2.0, 3.0, 6.0]).unwrap();
        assert_eq!(s.mean, 3.0);
        // sample variance (4 + 1 + 0 + 9) / 3
        assert!((s.std.unwrap() - (14.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!((s.min, s.max), (1.0, 6.0));
        assert_eq!(spread(&[2.5]).unwrap().std, None);
        assert!(spread(&[]).is_none());
        assert_eq!(efficiency(2.0, 0.25), 2.0);
    }
}
