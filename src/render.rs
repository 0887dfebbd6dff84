//! The render driver: the image is cut into tiles, rendered in parallel by rayon, and the
//! tiles' film sums are merged in a fixed order. Every pixel sample draws from the scene's
//! sampler keyed by (seed, pixel, sample index), so the result is bit-identical for any
//! number of threads.
//!
//! Two engines trace a tile's camera paths ([`Engine`]): the scalar engine, one path at a
//! time, and for the `path` integrator the lane engine ([`crate::integrator::lanes`]), 16
//! paths side by side, whose results are added to the film in the scalar engine's order so
//! that its image is the same bit for bit.

use crate::error::{Error, Result};
use crate::film::{Film, FilmTile};
use crate::integrator::aov::AovIntegrator;
use crate::integrator::lanes::path::{trace_tile, CameraSample, TileQueue};
use crate::integrator::lanes::LaneStats;
use crate::integrator::ptracer::Splat;
use crate::integrator::{Integrator, ParticleTracer, PathStats};
use crate::scene::description::SceneDescription;
use crate::scene::Scene;
use crate::simd::Backend;
use crate::spectrum::to_rgb;
use crate::spectrum::{from_rgb, Mode, NO_WAVELENGTHS};
use glam::{Vec2, Vec4};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// What a render walks: the scene, and the integrator built for it. The scene does not know
/// its integrator; the integrator is handed the scene.
pub struct Job {
    pub scene: Scene,
    pub integrator: Integrator,
    /// The engine that renders camera paths (scalar unless set).
    pub engine: Engine,
}

impl Job {
    /// Builds the scene of `desc`, then its integrator.
    pub fn build(desc: &SceneDescription) -> Result<Job> {
        let scene = crate::scene::build::build(desc)?;
        let integrator = Integrator::build(&desc.integrator, &scene)?;
        if scene.mode == Mode::Spectral && !integrator.supports_spectral() {
            return Err(Error::Invalid(format!(
                "spectral mode renders with the path, direct, volpath, volpathmis, ptracer, bdpt and aov integrators; {} renders in RGB mode only (docs/spectral.md says why)",
                integrator.name()
            )));
        }
        Ok(Job {
            scene,
            integrator,
            engine: Engine::Scalar,
        })
    }

    /// Loads a Mitsuba XML file with `-D name=value` overrides and builds it.
    pub fn load(path: &std::path::Path, defines: &[(String, String)]) -> Result<Job> {
        Self::load_in(path, defines, Mode::Rgb)
    }

    /// [`Job::load`] rendering in `mode`.
    pub fn load_in(
        path: &std::path::Path,
        defines: &[(String, String)],
        mode: Mode,
    ) -> Result<Job> {
        let mut desc = Scene::load_description(path, defines)?;
        desc.mode = mode;
        Self::build(&desc)
    }

    /// Builds a scene from XML text; `path` locates it for messages and relative files.
    pub fn from_xml_str(
        text: &str,
        path: &std::path::Path,
        defines: &[(String, String)],
    ) -> Result<Job> {
        Self::build(&Scene::description_from_xml_str(text, path, defines)?)
    }

    /// The image `settings` asks for, on the job's engine ([`render_with`]).
    pub fn render(
        &self,
        settings: &RenderSettings,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<RenderOutput> {
        render_with(
            &self.scene,
            &self.integrator,
            self.engine,
            settings,
            progress,
        )
    }
}

/// Which engine renders the camera paths of a `path` scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Engine {
    /// One path at a time: every integrator; the oracle of the lane engine.
    #[default]
    Scalar,
    /// Paths side by side in SIMD lanes ([`crate::integrator::lanes`]), on the given backend
    /// or (`None`) the widest this processor runs. It covers the `path` integrator and gives
    /// the scalar engine's image bit for bit; other integrators run on the scalar engine.
    Lanes(Option<Backend>),
}

/// The engine a render ran on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EngineRan {
    #[default]
    Scalar,
    Lanes(Backend),
    /// The lane engine was asked for, but does not cover this integrator (named): the
    /// scalar engine ran.
    ScalarFallback(&'static str),
}

impl std::fmt::Display for EngineRan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EngineRan::Scalar => write!(f, "scalar"),
            EngineRan::Lanes(b) => write!(f, "lanes ({b}, {} wide)", b.width()),
            EngineRan::ScalarFallback(name) => write!(
                f,
                "scalar (the lane engine covers the path integrator, not {name})"
            ),
        }
    }
}

impl Engine {
    /// What a render of `integrator` on this engine runs on; an error if a lane backend
    /// was named that this processor does not run.
    pub fn resolve(self, integrator: &Integrator) -> Result<EngineRan> {
        Ok(match (self, integrator) {
            (Engine::Scalar, _) => EngineRan::Scalar,
            (Engine::Lanes(backend), Integrator::Path(_)) => {
                let b = backend.unwrap_or_else(Backend::best);
                if !b.supported() {
                    return Err(Error::Invalid(format!(
                        "the {b} lane backend needs instructions this processor does not have"
                    )));
                }
                EngineRan::Lanes(b)
            }
            (Engine::Lanes(_), other) => EngineRan::ScalarFallback(other.name()),
        })
    }
}

/// Side of a square render tile, in pixels.
pub const TILE_SIZE: usize = 16;

#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Samples per pixel.
    pub spp: u32,
    /// Index of the first sample of each pixel: a render with offset k continues one that
    /// drew samples 0..k, so that films can be added up progressively (see [`Film::add`]).
    pub first_sample: u64,
    pub seed: u64,
    /// Worker threads; `None` for rayon's default (one per core).
    pub threads: Option<usize>,
    /// The sampler, if not the scene's (a convergence ladder renders each step with the
    /// sampler's points per pass set to that step's spp).
    pub sampler: Option<crate::sampler::Sampler>,
}

/// What a render measured besides the image.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderStats {
    /// Camera paths traced (pixels × spp).
    pub paths: u64,
    pub path: PathStats,
    /// Samples whose value was NaN or infinite: dropped, not accumulated.
    pub nonfinite: u64,
    /// Wall-clock time of the sampling loop, in seconds.
    pub seconds: f64,
    /// The engine that ran (the last pass's, for a progressive render).
    pub engine: EngineRan,
    /// How full the lane engine's lanes were (zero on the scalar engine).
    pub lanes: LaneStats,
    /// `bdpt`: the share of samples that traced a light subpath.
    pub light_paths: Option<f32>,
}

impl RenderStats {
    /// Millions of camera paths per second.
    pub fn mpaths_per_second(&self) -> f64 {
        self.paths as f64 / self.seconds.max(1e-9) / 1e6
    }
}

pub struct RenderOutput {
    pub film: Film,
    pub stats: RenderStats,
}

struct TileResult {
    tile: FilmTile,
    stats: PathStats,
    lanes: LaneStats,
    nonfinite: u64,
}

impl TileResult {
    /// Adds the sample of pixel (x, y) with value `l` at film position `pos`, or counts it
    /// as non-finite; samples of the border beyond the image (`size`) only lend their
    /// splats (the image's sample count is its own pixels').
    #[inline(always)]
    fn add(
        &mut self,
        (x, y): (i64, i64),
        pos: Vec2,
        l: crate::spectrum::Spectrum,
        size: (i64, i64),
    ) {
        if l.is_finite() {
            self.tile.add_sample(pos, to_rgb(l));
            if !((0..size.0).contains(&x) && (0..size.1).contains(&y)) {
                self.tile.samples -= 1;
            }
        } else {
            self.nonfinite += 1;
        }
    }
}

/// Hands each finite splat of a row to `add` (film position in pixels, value) and counts
/// the others as non-finite samples, for the light-tracing integrators' passes.
fn add_finite_splats(
    splats: &[Splat],
    res: Vec2,
    nonfinite: &mut u64,
    mut add: impl FnMut(Vec2, crate::spectrum::Spectrum),
) {
    for sp in splats {
        if sp.value.is_finite() {
            add(sp.film * res, sp.value);
        } else {
            *nonfinite += 1;
        }
    }
}

/// The camera sample `s` (sample index `first_sample + s`) of pixel (x, y): its sample
/// stream, film position (pixels) and ray. Both engines make their camera rays here.
#[inline(always)]
fn camera_sample(
    scene: &Scene,
    sampler: crate::sampler::Sampler,
    settings: &RenderSettings,
    (x, y): (i64, i64),
    s: u64,
) -> CameraSample {
    let (pixel, size) = scene.sample_key(x, y);
    let inv_res = Vec2::new(1.0 / scene.width as f32, 1.0 / scene.height as f32);
    let mut stream = sampler.stream(settings.seed, pixel, size, settings.first_sample + s);
    // Mitsuba's sampler dimension order: pixel position, then aperture.
    let pos = Vec2::new(x as f32, y as f32) + stream.next_2d();
    let ray = if scene.camera.needs_aperture_sample() {
        let u_lens = stream.next_2d();
        scene.camera.generate_ray_lens(pos * inv_res, u_lens)
    } else {
        scene.camera.generate_ray(pos * inv_res)
    };
    (stream, pos, ray)
}

/// Renders the samples of one tile and adds them to its film tile in the canonical order
/// (pixels row by row, samples ascending) on which the image's bits depend: see the film
/// module's "order of accumulation".
fn render_tile(
    scene: &Scene,
    integrator: &Integrator,
    engine: EngineRan,
    settings: &RenderSettings,
    x0: i64,
    y0: i64,
) -> TileResult {
    // (the image, enlarged by the sampled border on every side)
    let b = scene.sample_border as i64;
    let (width, height) = (scene.width as i64, scene.height as i64);
    let w = (TILE_SIZE as i64).min(width + b - x0) as usize;
    let h = (TILE_SIZE as i64).min(height + b - y0) as usize;
    let mut r = TileResult {
        tile: FilmTile::new_at(x0, y0, w, h, scene.filter),
        stats: PathStats::default(),
        lanes: LaneStats::default(),
        nonfinite: 0,
    };
    let sampler = settings.sampler.unwrap_or(scene.sampler);
    let spp = settings.spp as usize;
    if let (EngineRan::Lanes(backend), Integrator::Path(path)) = (engine, integrator) {
        // The tile's samples in the scalar engine's order, traced in lanes, then added to
        // the film in that order.
        let pixel = |q: usize| {
            let p = q / spp.max(1);
            (x0 + (p % w) as i64, y0 + (p / w) as i64)
        };
        let camera = |q: usize| camera_sample(scene, sampler, settings, pixel(q), (q % spp) as u64);
        let queue = TileQueue {
            scene,
            path,
            total: w * h * spp,
            camera: &camera,
        };
        let mut out = vec![(Vec2::ZERO, crate::spectrum::Spectrum::ZERO); queue.total];
        let mut wavelengths = match scene.mode {
            Mode::Rgb => Vec::new(),
            Mode::Spectral => vec![(Vec4::ZERO, Vec4::ZERO); queue.total],
        };
        let ran = trace_tile(
            backend,
            &queue,
            &mut out,
            &mut wavelengths,
            &mut r.stats,
            &mut r.lanes,
        );
        assert!(ran, "the {backend} backend was checked before the render");
        for (q, &(pos, l)) in out.iter().enumerate() {
            // Spectral mode: the film's linear sRGB of the values times their weights, as
            // the scalar engine converts them.
            let l = match wavelengths.get(q) {
                Some(&(wl, weight)) => from_rgb(crate::spectral::spectrum_to_srgb(l * weight, wl)),
                None => l,
            };
            r.add(pixel(q), pos, l, (width, height));
        }
        return r;
    }
    for y in y0..y0 + h as i64 {
        for x in x0..x0 + w as i64 {
            for s in 0..settings.spp as u64 {
                let (mut stream, pos, ray) = camera_sample(scene, sampler, settings, (x, y), s);
                let l = match scene.mode {
                    Mode::Rgb => {
                        integrator.li(scene, ray, NO_WAVELENGTHS, &mut stream, &mut r.stats)
                    }
                    Mode::Spectral => {
                        // Mitsuba's spectral variants: four wavelengths per path from one
                        // sample, the film's linear sRGB of the path's values times their
                        // weights (1 / pdf).
                        let (wl, weight) = crate::spectral::sample_wavelengths(stream.next_1d());
                        let l = integrator.li(scene, ray, wl, &mut stream, &mut r.stats);
                        if integrator.outputs_spectrum() {
                            from_rgb(crate::spectral::spectrum_to_srgb(l * weight, wl))
                        } else {
                            l
                        }
                    }
                };
                r.add((x, y), pos, l, (width, height));
            }
        }
    }
    r
}

/// A pool of `threads` workers (default: one per core).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err(Error::Invalid("--threads must be at least 1".into()));
        }
        builder = builder.num_threads(n);
    }
    builder
        .build()
        .map_err(|e| Error::Invalid(format!("cannot start worker threads: {e}")))
}

/// Renders `scene` with `integrator` at `settings.spp` samples per pixel, on the scalar
/// engine. `progress(done, total)` is called (from worker threads) as samples complete.
pub fn render(
    scene: &Scene,
    integrator: &Integrator,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderOutput> {
    render_with(scene, integrator, Engine::Scalar, settings, progress)
}

/// [`render`] on `engine` (the lane engine where it covers the integrator; the statistics
/// say which ran).
pub fn render_with(
    scene: &Scene,
    integrator: &Integrator,
    engine: Engine,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderOutput> {
    let requested = engine;
    let engine = engine.resolve(integrator)?;
    let pool = thread_pool(settings.threads)?;
    match integrator {
        Integrator::ParticleTracer(pt) => {
            let mut out = render_particles(scene, pt, settings, &pool, progress);
            out.stats.engine = engine;
            return Ok(out);
        }
        Integrator::Sppm(sppm) => {
            let mut out = sppm.render(scene, settings, &pool, progress)?;
            out.stats.engine = engine;
            return Ok(out);
        }
        Integrator::Bdpt(b) => {
            let b = b.resolved(scene, settings.seed, settings.spp as u64, &pool);
            if b.light_share() > 0.0 {
                let mut out = render_bdpt(scene, &b, settings, &pool, progress);
                out.stats.engine = engine;
                return Ok(out);
            }
            // No light subpaths: the strategies s ≤ 1 alone, the path tracer's estimator
            // (on the engine asked for: the lane engine covers the path tracer).
            let path = Integrator::Path(b.path_tracer());
            let mut out = render_with(scene, &path, requested, settings, progress)?;
            out.stats.light_paths = Some(0.0);
            return Ok(out);
        }
        _ => {}
    }
    // Tiles of the image, or of the image and the border Mitsuba's `sample_border` samples.
    let b = scene.sample_border as i64;
    let (width, height) = (scene.width as i64, scene.height as i64);
    let tiles: Vec<(i64, i64)> = (-b..height + b)
        .step_by(TILE_SIZE)
        .flat_map(|y| (-b..width + b).step_by(TILE_SIZE).map(move |x| (x, y)))
        .collect();
    let total = ((width + 2 * b) * (height + 2 * b)) as u64 * settings.spp as u64;
    let done = AtomicU64::new(0);
    let start = Instant::now();
    let prepared;
    let integrator = match integrator {
        Integrator::Radiosity(r) => {
            // Solved within the render's time and threads (kept for further passes), and
            // handed to the samples directly rather than through the integrator's lock.
            let solution = pool.install(|| r.prepare(scene, settings.seed));
            prepared = Integrator::Radiosity(r.with_solution(solution));
            &prepared
        }
        i => i,
    };
    let results: Vec<TileResult> = pool.install(|| {
        tiles
            .par_iter()
            .map(|&(x, y)| {
                let r = render_tile(scene, integrator, engine, settings, x, y);
                let pixels =
                    (TILE_SIZE as i64).min(width + b - x) * (TILE_SIZE as i64).min(height + b - y);
                let n = pixels as u64 * settings.spp as u64;
                progress(done.fetch_add(n, Ordering::Relaxed) + n, total);
                r
            })
            .collect()
    });
    let seconds = start.elapsed().as_secs_f64();
    let mut film = Film::new(scene.width, scene.height, scene.filter);
    let mut stats = RenderStats {
        paths: total,
        seconds,
        engine,
        ..Default::default()
    };
    for r in &results {
        film.merge(&r.tile);
        stats.path += r.stats;
        stats.lanes += r.lanes;
        stats.nonfinite += r.nonfinite;
    }
    Ok(RenderOutput { film, stats })
}

/// Light tracing's work item: the particles of sample `s` of one image row (one particle per
/// pixel, each drawing from the sample stream of (seed, pixel, sample) as a camera sample
/// would).
struct ParticleRow {
    splats: Vec<Splat>,
    stats: PathStats,
}

/// Work items traced in parallel before their splats are added, in order, to the film.
const PARTICLE_BATCH: usize = 256;

/// Renders a light tracer: `spp · width · height` particles. The splats of sample s of all
/// pixels form one pass, added to the film as one sample per pixel
/// ([`Film::add_light_pass`]). Rows are traced in parallel and their splats added in a
/// fixed order (sample, row, particle), so the image is bit-identical for any thread count.
fn render_particles(
    scene: &Scene,
    pt: &ParticleTracer,
    settings: &RenderSettings,
    pool: &rayon::ThreadPool,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> RenderOutput {
    let (w, h) = (scene.width, scene.height);
    let spp = settings.spp as usize;
    let sampler = settings.sampler.unwrap_or(scene.sampler);
    let size = (w as u32, h as u32);
    let res = Vec2::new(w as f32, h as f32);
    let total = (w * h) as u64 * settings.spp as u64;
    let start = Instant::now();
    let mut film = Film::new(w, h, scene.filter);
    let mut pass = vec![[0.0f64; 3]; w * h];
    let mut stats = RenderStats {
        paths: total,
        ..Default::default()
    };
    let items = spp * h;
    let mut done = 0u64;
    for batch in (0..items).step_by(PARTICLE_BATCH) {
        let end = (batch + PARTICLE_BATCH).min(items);
        let rows: Vec<ParticleRow> = pool.install(|| {
            (batch..end)
                .into_par_iter()
                .map(|k| {
                    let (s, y) = (k / h, k % h);
                    let mut row = ParticleRow {
                        splats: Vec::new(),
                        stats: PathStats::default(),
                    };
                    for x in 0..w {
                        let mut stream = sampler.stream(
                            settings.seed,
                            (x as u32, y as u32),
                            size,
                            settings.first_sample + s as u64,
                        );
                        match scene.mode {
                            Mode::Rgb => pt.trace(
                                scene,
                                NO_WAVELENGTHS,
                                &mut stream,
                                &mut row.stats,
                                &mut row.splats,
                            ),
                            Mode::Spectral => {
                                // Four wavelengths per particle, drawn as for camera paths
                                // (Mitsuba draws them from the emitter's spectrum: the same
                                // expectation, another variance); each splat is converted
                                // to linear sRGB with the wavelengths' weights.
                                let first = row.splats.len();
                                let (wl, weight) =
                                    crate::spectral::sample_wavelengths(stream.next_1d());
                                pt.trace(scene, wl, &mut stream, &mut row.stats, &mut row.splats);
                                for sp in &mut row.splats[first..] {
                                    sp.value = from_rgb(crate::spectral::spectrum_to_srgb(
                                        sp.value * weight,
                                        wl,
                                    ));
                                }
                            }
                        }
                    }
                    row
                })
                .collect()
        });
        for (k, row) in (batch..end).zip(rows) {
            if k > 0 && k % h == 0 {
                film.add_light_pass(&pass);
                pass.iter_mut().for_each(|p| *p = [0.0; 3]);
            }
            stats.path += row.stats;
            add_finite_splats(&row.splats, res, &mut stats.nonfinite, |p, v| {
                film.splat(&mut pass, p, to_rgb(v))
            });
        }
        done += ((end - batch) * w) as u64;
        progress(done, total);
    }
    if spp > 0 {
        film.add_light_pass(&pass);
    }
    stats.seconds = start.elapsed().as_secs_f64();
    RenderOutput { film, stats }
}

/// Bidirectional path tracing's work item: the pixel samples of sample index `s` of one row
/// of the sampled pixels (the image and Mitsuba's `sample_border` beyond it).
#[derive(Default)]
struct BdptRow {
    /// Each pixel sample's film position (pixels) and camera-side radiance.
    samples: Vec<(Vec2, crate::spectrum::Spectrum)>,
    splats: Vec<Splat>,
    stats: PathStats,
}

/// The shares of samples tracing a light subpath that `bdpt`'s pilot chooses among. The
/// last, 0, only where every path has a camera-side strategy
/// ([`crate::integrator::Bdpt::camera_side_complete`]): no light subpaths at all, and so
/// the path tracer's estimator.
pub const LIGHT_PATH_SHARES: [f32; 8] = [1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625, 0.0];

/// The cost of evaluating one connection s ≥ 2 (its BSDFs and MIS weight), in rays: the
/// pilot's cost model is rays + this × connections (calibrated on the Cornell box, see
/// docs/bdpt.md).
pub const CONNECTION_COST: f64 = 0.4;

/// What a pilot render of `bdpt` adds up (all samples tracing both subpaths): for each
/// share c of [`LIGHT_PATH_SHARES`], the sum over pixels of the variance per sample the
/// pixel would have with share c — each sample's second moment, its contributions
/// re-weighted with c and the light side's (s ≥ 2) traced with probability c and divided by
/// it, so that in expectation over that choice |X_cam|² + 2 X_cam·X_light + (|X_light|² +
/// Σ |splat|²) / c (summed over channels; splats land in other pixels, so their cross terms
/// are left out), averaged over the pixel's samples, less the squared mean; and the work of
/// each side.
#[derive(Clone, Copy, Debug, Default)]
pub struct PilotSums {
    pub moments: [f64; LIGHT_PATH_SHARES.len()],
    pub work: crate::integrator::bdpt::Work,
}

/// One pilot sample's contributions at one candidate share: the camera-side strategies'
/// and the light side's (t ≥ 2) radiance, and the light-tracing splats' squares.
#[derive(Clone, Copy, Default)]
struct PilotSample {
    camera: crate::spectrum::Spectrum,
    light: crate::spectrum::Spectrum,
    splats: f64,
}

/// The pilot's dot product over the channels (RGB mode: the fourth lane is a copy of green;
/// spectral mode: the four wavelengths stand for the three channels).
fn dot(mode: Mode, a: crate::spectrum::Spectrum, b: crate::spectrum::Spectrum) -> f64 {
    match mode {
        Mode::Rgb => a.truncate().dot(b.truncate()) as f64,
        Mode::Spectral => 0.75 * a.dot(b) as f64,
    }
}

impl PilotSums {
    fn add(&mut self, o: &PilotSums) {
        for (a, b) in self.moments.iter_mut().zip(o.moments) {
            *a += b;
        }
        self.work.camera += o.work.camera;
        self.work.light += o.work.light;
        self.work.connections += o.work.connections;
    }
}

/// The pilot's choice: the share, and per candidate share its modelled cost per sample (in
/// rays) and image variance per sample (summed over pixels and channels).
#[derive(Clone, Debug)]
pub struct LightPathChoice {
    pub share: f32,
    pub cost: Vec<f64>,
    pub variance: Vec<f64>,
    /// Whether share 0 is a candidate: every path of the scene has a camera-side strategy
    /// ([`crate::integrator::Bdpt::camera_side_complete`]).
    pub camera_side_complete: bool,
}

impl LightPathChoice {
    /// The share of least cost × variance among those of at least `floor` (and 0, where
    /// the camera side is complete: no light subpath, so no pixel short of them); 1 when
    /// the pilot saw no variance.
    pub fn best(&self, floor: f32) -> f32 {
        let mut share = 1.0;
        if self.variance[0] > 0.0 && self.variance[0].is_finite() {
            let mut best = f64::INFINITY;
            for (k, &c) in LIGHT_PATH_SHARES.iter().enumerate() {
                let e = self.cost[k] * self.variance[k];
                let allowed = if c == 0.0 {
                    self.camera_side_complete
                } else {
                    c >= floor
                };
                if allowed && e < best {
                    best = e;
                    share = c;
                }
            }
        }
        share
    }
}

/// Chooses the share of samples that trace a light subpath for `bdpt` on `scene` by a pilot
/// render (efficiency-aware MIS, after Grittmann, Yazici, Georgiev and Slusallek 2022): a
/// few samples per pixel with every sample tracing both subpaths (seed derived from `seed`,
/// so that every part and resumption of a render chooses the same), from which, for each
/// candidate share c, the image variance per sample is estimated (each pilot sample's
/// contributions re-weighted for c: [`PilotSums`]; per pixel, the second moment less the
/// squared mean, both from that pixel's samples), and the cost per sample as camera-side
/// rays + c × (light-side rays + connections × [`CONNECTION_COST`]). The share with the
/// least cost × variance wins; 1 when the pilot saw no variance. Deterministic: each row
/// is one work item, and rows are summed in order.
pub fn choose_light_paths(
    scene: &Scene,
    bdpt: &crate::integrator::Bdpt,
    seed: u64,
    pool: &rayon::ThreadPool,
) -> LightPathChoice {
    const K: usize = LIGHT_PATH_SHARES.len();
    let b = scene.sample_border as i64;
    let (w, h) = (scene.width as i64, scene.height as i64);
    let pixels = ((w + 2 * b) * (h + 2 * b)) as usize;
    let n = (PILOT_SAMPLES.div_ceil(pixels.max(1)) as u64).clamp(4, 64);
    let pilot = crate::integrator::Bdpt {
        light_paths: Some(1.0),
        shadow_roulette: false,
        ..bdpt.clone()
    };
    let sampler = scene.sampler;
    let settings = RenderSettings {
        spp: n as u32,
        first_sample: 0,
        seed: seed ^ PILOT_SEED,
        threads: None,
        sampler: None,
    };
    let rows: Vec<PilotSums> = pool.install(|| {
        (-b..h + b)
            .into_par_iter()
            .map_init(crate::integrator::bdpt::Scratch::default, |scratch, y| {
                let mut row = PilotSums::default();
                let work = scratch.work;
                let mut stats = PathStats::default();
                let mut splats = Vec::new();
                for x in -b..w + b {
                    // Per candidate: Σ second moments, Σ Y, Σ |Y|² (Y the camera-side
                    // radiance with the light side always traced) over the pixel's samples.
                    let mut second = [0.0f64; K];
                    let mut sum_y = [crate::spectrum::Spectrum::ZERO; K];
                    let mut sum_y2 = [0.0f64; K];
                    for s in 0..n {
                        let (mut stream, _, ray) =
                            camera_sample(scene, sampler, &settings, (x, y), s);
                        let wl = match scene.mode {
                            Mode::Rgb => NO_WAVELENGTHS,
                            Mode::Spectral => {
                                crate::spectral::sample_wavelengths(stream.next_1d()).0
                            }
                        };
                        let mut parts = [PilotSample::default(); K];
                        let mut record = |c: &crate::integrator::bdpt::Connection| {
                            let m = c.mis;
                            let v = c.value / c.kept;
                            for (part, &share) in parts.iter_mut().zip(&LIGHT_PATH_SHARES) {
                                let own = if c.s >= 2 { share } else { 1.0 } as f64;
                                let wt = own * own
                                    / (m.camera_side + (share as f64).powi(2) * m.light_side);
                                let xv = v * wt as f32;
                                if !wt.is_finite() || !xv.is_finite() {
                                    continue;
                                }
                                if c.t == 1 {
                                    part.splats += dot(scene.mode, xv, xv);
                                } else if c.s >= 2 {
                                    part.light += xv;
                                } else {
                                    part.camera += xv;
                                }
                            }
                        };
                        pilot.sample_recorded(
                            scene,
                            ray,
                            wl,
                            &mut stream,
                            scratch,
                            &mut stats,
                            &mut splats,
                            &mut record,
                        );
                        splats.clear();
                        for k in 0..K {
                            let (p, share) = (&parts[k], LIGHT_PATH_SHARES[k] as f64);
                            let d = |a, b| dot(scene.mode, a, b);
                            // In expectation over tracing the light side with probability
                            // c and dividing it by c.
                            // (At share 0 the light side is never traced: nothing.)
                            let light = if share > 0.0 {
                                (d(p.light, p.light) + p.splats) / share
                            } else {
                                0.0
                            };
                            second[k] += d(p.camera, p.camera) + 2.0 * d(p.camera, p.light) + light;
                            let y = p.camera + p.light;
                            sum_y[k] += y;
                            sum_y2[k] += d(y, y);
                        }
                    }
                    // Variance per sample: E[X²] − μ², μ² estimated without bias as
                    // m² − s²/n (s² the sample variance of Y). Splats land in other pixels,
                    // each a tiny part of their mean: their squares count whole.
                    let nf = n as f64;
                    for k in 0..K {
                        let m = sum_y[k] / nf as f32;
                        let m2 = dot(scene.mode, m, m);
                        let s2 = (sum_y2[k] - nf * m2) / (nf - 1.0);
                        row.moments[k] += second[k] / nf - (m2 - s2 / nf);
                    }
                }
                row.work = crate::integrator::bdpt::Work {
                    camera: scratch.work.camera - work.camera,
                    light: scratch.work.light - work.light,
                    connections: scratch.work.connections - work.connections,
                };
                row
            })
            .collect()
    });
    let mut sums = PilotSums::default();
    for r in &rows {
        sums.add(r);
    }
    let samples = n as f64 * pixels as f64;
    let wk = sums.work;
    let (camera, light) = (
        wk.camera as f64 / samples,
        (wk.light as f64 + CONNECTION_COST * wk.connections as f64) / samples,
    );
    let cost: Vec<f64> = LIGHT_PATH_SHARES
        .iter()
        .map(|&c| camera + c as f64 * light)
        .collect();
    let variance = sums.moments.to_vec();
    let mut choice = LightPathChoice {
        share: 1.0,
        cost,
        variance,
        camera_side_complete: bdpt.camera_side_complete(scene),
    };
    choice.share = choice.best(0.0);
    choice
}

/// About how many pixel samples `bdpt`'s pilot draws (at least 4 and at most 64 per
/// pixel).
const PILOT_SAMPLES: usize = 1 << 17;
/// The pilot's seed is the render's with these bits flipped: its samples are not the
/// render's.
const PILOT_SEED: u64 = 0x5049_4c4f_5420_5345;

/// Renders a bidirectional path tracer. Each sample index is one pass over all the sampled
/// pixels: their camera samples and light-tracing splats are added to a
/// [`crate::film::MixedPass`] in a fixed order (row, pixel), and the pass to the film as one
/// sample per pixel ([`Film::add_mixed_pass`]); rows are traced in parallel, so the image is
/// bit-identical at any thread count, and a render of samples [a, b) is the same sums as its
/// parts rendered separately.
fn render_bdpt(
    scene: &Scene,
    bdpt: &crate::integrator::Bdpt,
    settings: &RenderSettings,
    pool: &rayon::ThreadPool,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> RenderOutput {
    let b = scene.sample_border as i64;
    let (w, h) = (scene.width as i64, scene.height as i64);
    let (cols, rows) = ((w + 2 * b) as usize, (h + 2 * b) as usize);
    let spp = settings.spp as usize;
    let sampler = settings.sampler.unwrap_or(scene.sampler);
    let res = Vec2::new(w as f32, h as f32);
    let total = (cols * rows) as u64 * settings.spp as u64;
    let start = Instant::now();
    let mut film = Film::new(scene.width, scene.height, scene.filter);
    let mut pass =
        crate::film::MixedPass::new(scene.width, scene.height, scene.filter, scene.sample_border);
    let mut stats = RenderStats {
        paths: total,
        light_paths: Some(bdpt.light_share()),
        ..Default::default()
    };
    let items = spp * rows;
    let mut done = 0u64;
    for batch in (0..items).step_by(PARTICLE_BATCH) {
        let end = (batch + PARTICLE_BATCH).min(items);
        let results: Vec<BdptRow> = pool.install(|| {
            (batch..end)
                .into_par_iter()
                .map_init(crate::integrator::bdpt::Scratch::default, |scratch, k| {
                    let (s, y) = (k / rows, (k % rows) as i64 - b);
                    let mut row = BdptRow::default();
                    for x in -b..w + b {
                        // The camera ray as the path tracer draws it.
                        let (mut stream, pos, ray) =
                            camera_sample(scene, sampler, settings, (x, y), s as u64);
                        let l = match scene.mode {
                            Mode::Rgb => bdpt.sample(
                                scene,
                                ray,
                                NO_WAVELENGTHS,
                                &mut stream,
                                scratch,
                                &mut row.stats,
                                &mut row.splats,
                            ),
                            Mode::Spectral => {
                                // One set of wavelengths per sample, drawn after the camera
                                // ray as for the path tracer, shared by both subpaths; the
                                // radiance and this sample's splats are converted with
                                // their weights.
                                let (wl, weight) =
                                    crate::spectral::sample_wavelengths(stream.next_1d());
                                let first = row.splats.len();
                                let l = bdpt.sample(
                                    scene,
                                    ray,
                                    wl,
                                    &mut stream,
                                    scratch,
                                    &mut row.stats,
                                    &mut row.splats,
                                );
                                let to_srgb = |v: crate::spectrum::Spectrum| {
                                    from_rgb(crate::spectral::spectrum_to_srgb(v * weight, wl))
                                };
                                for sp in &mut row.splats[first..] {
                                    sp.value = to_srgb(sp.value);
                                }
                                to_srgb(l)
                            }
                        };
                        row.samples.push((pos, l));
                    }
                    row
                })
                .collect()
        });
        for (k, row) in (batch..end).zip(results) {
            if k > 0 && k % rows == 0 {
                film.add_mixed_pass(&pass);
                pass.clear();
            }
            stats.path += row.stats;
            for (pos, l) in row.samples {
                if l.is_finite() {
                    pass.add_sample(pos, to_rgb(l));
                } else {
                    stats.nonfinite += 1;
                }
            }
            add_finite_splats(&row.splats, res, &mut stats.nonfinite, |p, v| {
                pass.add_splat(p, to_rgb(v))
            });
        }
        done += ((end - batch) * cols) as u64;
        progress(done, total);
    }
    if spp > 0 {
        film.add_mixed_pass(&pass);
    }
    stats.seconds = start.elapsed().as_secs_f64();
    RenderOutput { film, stats }
}

/// The channels of an AOV render: `(name, values)` per channel, row-major from the top row.
pub type Channels = crate::io::exr::NamedChannels;

/// Renders every channel group of the `aov` integrator at `spp` with `seed`, one group after
/// the other, each with the same pixel samples.
pub fn render_channels(
    scene: &Scene,
    aov: &AovIntegrator,
    spp: u32,
    seed: u64,
    threads: Option<usize>,
) -> Result<(Channels, RenderStats)> {
    let settings = RenderSettings {
        spp,
        seed,
        threads,
        sampler: None,
        first_sample: 0,
    };
    let mut channels = Vec::new();
    let mut stats = RenderStats::default();
    for (group, (name, suffixes)) in aov.groups().iter().enumerate() {
        let integrator = Integrator::Aov(AovIntegrator {
            group,
            ..aov.clone()
        });
        let out = render(scene, &integrator, &settings, &|_, _| {})?;
        let image = out.film.image();
        for (c, suffix) in suffixes.iter().enumerate() {
            channels.push((
                format!("{name}.{suffix}"),
                image.iter().map(|p| p[c]).collect(),
            ));
        }
        stats.paths += out.stats.paths;
        stats.path += out.stats.path;
        stats.nonfinite += out.stats.nonfinite;
        stats.seconds += out.stats.seconds;
    }
    Ok((channels, stats))
}
