//! Split renders: the plan of `render --part i/N` (which passes each part holds), rendering a
//! part (stoppable and resumable from its checkpoint), and the merge of part files into the
//! render they make up.

use super::{
    pass_spp, write_checkpoint_retrying, Checkpoint, CheckpointHeader, Checkpointing, StopReason,
};
use crate::error::{Error, Result};
use crate::film::ExactFilm;
use crate::render::{render_with, Job, RenderSettings, RenderStats};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

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
    ///
    /// [`ProgressiveSettings::stop`]: super::ProgressiveSettings::stop
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
    ///
    /// [`Progress`]: super::Progress
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
    // (bdpt's pilot: for the whole plan, so that every part chooses the same.)
    let integrator = job
        .integrator
        .resolved(scene, settings.seed, plan.plan_spp, &pool);
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
        let out = render_with(
            scene,
            &integrator,
            job.engine,
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
        part.stats.lanes += out.stats.lanes;
        part.stats.engine = out.stats.engine;
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
        return refuse("from another scene (or other -D values, mesh files or --mode)".into());
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
            return differs("from another scene (or other -D values, mesh files or --mode)");
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
