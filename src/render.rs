//! The render driver: the image is cut into tiles, rendered in parallel by rayon, and the
//! tiles' film sums are merged in a fixed order. Every pixel sample draws from the scene's
//! sampler keyed by (seed, pixel, sample index), so the result is bit-identical for any
//! number of threads.

use crate::error::{Error, Result};
use crate::film::{Film, FilmTile};
use crate::integrator::PathStats;
use crate::scene::Scene;
use glam::Vec2;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

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
    nonfinite: u64,
}

fn render_tile(scene: &Scene, settings: &RenderSettings, x0: usize, y0: usize) -> TileResult {
    let w = TILE_SIZE.min(scene.width - x0);
    let h = TILE_SIZE.min(scene.height - y0);
    let mut tile = FilmTile::new(x0, y0, w, h, scene.filter);
    let mut stats = PathStats::default();
    let mut nonfinite = 0;
    let inv_res = Vec2::new(1.0 / scene.width as f32, 1.0 / scene.height as f32);
    let sampler = settings.sampler.unwrap_or(scene.sampler);
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            let size = (scene.width as u32, scene.height as u32);
            for s in 0..settings.spp as u64 {
                let mut sampler = sampler.stream(
                    settings.seed,
                    (x as u32, y as u32),
                    size,
                    settings.first_sample + s,
                );
                // Mitsuba's sampler dimension order: pixel position, then aperture.
                let pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                let ray = if scene.camera.needs_aperture_sample() {
                    let u_lens = sampler.next_2d();
                    scene.camera.generate_ray_lens(pos * inv_res, u_lens)
                } else {
                    scene.camera.generate_ray(pos * inv_res)
                };
                let l = scene.integrator.li(scene, ray, &mut sampler, &mut stats);
                if l.is_finite() {
                    tile.add_sample(pos, l);
                } else {
                    nonfinite += 1;
                }
            }
        }
    }
    TileResult {
        tile,
        stats,
        nonfinite,
    }
}

/// Renders `scene` at `settings.spp` samples per pixel. `progress(done, total)` is called
/// (from worker threads) as samples complete.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderOutput> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = settings.threads {
        if n == 0 {
            return Err(Error::Invalid("--threads must be at least 1".into()));
        }
        builder = builder.num_threads(n);
    }
    let pool = builder
        .build()
        .map_err(|e| Error::Invalid(format!("cannot start worker threads: {e}")))?;
    let tiles: Vec<(usize, usize)> = (0..scene.height)
        .step_by(TILE_SIZE)
        .flat_map(|y| (0..scene.width).step_by(TILE_SIZE).map(move |x| (x, y)))
        .collect();
    let total = (scene.width * scene.height) as u64 * settings.spp as u64;
    let done = AtomicU64::new(0);
    let start = Instant::now();
    let results: Vec<TileResult> = pool.install(|| {
        tiles
            .par_iter()
            .map(|&(x, y)| {
                let r = render_tile(scene, settings, x, y);
                let pixels = TILE_SIZE.min(scene.width - x) * TILE_SIZE.min(scene.height - y);
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
        ..Default::default()
    };
    for r in &results {
        film.merge(&r.tile);
        stats.path += r.stats;
        stats.nonfinite += r.nonfinite;
    }
    Ok(RenderOutput { film, stats })
}
