//! Stochastic progressive photon mapping (`sppm`; Hachisuka and Jensen 2009, "Stochastic
//! progressive photon mapping"; pbrt-v4 §15.1 defines the algorithm as penumbra follows it).
//! Mitsuba 3 has no photon mapper: this integrator goes beyond the reference, for the
//! light → specular → diffuse → camera paths (caustics) that path tracing finds slowly and
//! from point lights not at all.
//!
//! Each iteration (one per sample per pixel):
//! 1. **Camera pass.** One ray per pixel (a uniform position in the pixel) follows delta
//!    bounces (mirrors, glass, null surfaces) to the first surface with a non-delta lobe,
//!    the pixel's *visible point*, adding the emission seen directly or through delta
//!    bounces and one sample of direct lighting there (next-event estimation, no MIS).
//!    Where a smooth `dielectric` or `thindielectric` picks reflection or transmission, the
//!    emission both lobes see next is added with its lobe's probability (splitting; the
//!    path goes on along the lobe picked), which pbrt-v4 does not do: see
//!    `Sppm::split_emission`.
//! 2. **Photon pass.** `photon_count` photons leave the emitters, chosen in proportion to
//!    their power ([`Emitter::power`]), by [`Emitter::sample_ray`]; they scatter by BSDF
//!    sampling in importance mode with Russian roulette (continuing with probability
//!    min(1, lum(β') / lum(β))). From its second surface hit on (the first is direct light,
//!    which step 1 estimates), a photon adds β f(ω_vp, ω_photon) to every visible point within
//!    that point's radius, found in a spatial hash grid of cell size the largest radius.
//! 3. **Update.** With M photons found this iteration, per pixel N' = N + αM,
//!    r' = r √(N'/(N + M)), τ' = (τ + β_vp Φ) r'²/r² (β_vp the camera path's throughput).
//!
//! The image is L = L_d / k + τ / (N_e π r²) after k iterations with N_e photons emitted in
//! all. `max_depth` counts path segments as for `path`: a photon deposit at its j-th
//! surface hit completes a path of d + j segments, d the camera segments to the visible
//! point, and counts only within `max_depth`. `initial_radius` 0 (the default) starts each
//! pixel at one footprint at the visible point (the distance along the camera path times
//! the pixel's angular size), so the radius adapts to the scene's scale. One footprint, not
//! more: the early iterations' blur decays slowly (r² falls as k^(−(1−α)/α) = k^(−1/2)
//! where photons arrive every iteration), and on `scenes/caustic-glass.xml` two footprints
//! left about 8× the squared error in the caustic after 4096 iterations; the noise they
//! save elsewhere did not make up for it in a minute's render (docs/light-paths.md).
//!
//! The estimate is biased (the radius blurs the illumination) and consistent: the bias
//! vanishes as the radius shrinks with α < 1. Known limitation, as in pbrt-v4: at a
//! visible point on a BSDF with both delta and non-delta lobes (the smooth `plastic`), the
//! delta lobe's reflection is lost. Deterministic for a seed at any thread count: photons
//! are traced in fixed chunks whose deposits are added in chunk order.
//!
//! [`Emitter::power`]: crate::emitter::Emitter::power
//! [`Emitter::sample_ray`]: crate::emitter::Emitter::sample_ray

use crate::bsdf::{BsdfSample, Spectrum};
use crate::film::Film;
use crate::geometry::Frame;
use crate::integrator::{emission_at, sample_emitter, PathStats};
use crate::material::ShadingBsdf;
use crate::render::{RenderOutput, RenderSettings, RenderStats};
use crate::sampler::SampleStream;
use crate::sampling::Distribution1D;
use crate::scene::Scene;
use crate::shape::SurfaceInteraction;
use crate::spectrum::to_rgb;
use crate::spectrum::NO_WAVELENGTHS;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct Sppm {
    /// Longest path, in segments; `u32::MAX` for unbounded.
    pub max_depth: u32,
    /// Photons emitted per iteration.
    pub photon_count: u64,
    /// Radius of every pixel's first gather (scene units); 0: the pixel's footprint.
    pub initial_radius: f32,
    /// Radius reduction: the share of new photons kept per iteration, in (0, 1).
    pub alpha: f32,
}

/// A pixel's visible point in one iteration. The buffer of a pixel lives across iterations
/// and its BSDF is filled in place ([`Scene::shading_bsdf_into`]): a `ShadingBsdf` is about
/// 2.5 KB, and moving one into a fresh point per pixel and iteration was 12% of an SPPM
/// render's time.
#[derive(Clone)]
struct VisiblePoint {
    /// Whether the pixel has a visible point this iteration (the other fields are stale
    /// when not).
    live: bool,
    p: Vec3,
    frame: Frame,
    /// Towards the camera, in the shading frame.
    wo: Vec3,
    bsdf: ShadingBsdf,
    /// Throughput of the camera path to the point.
    beta: Spectrum,
    /// Camera path segments to the point.
    depth: u32,
    /// Distance travelled from the camera (for the initial radius).
    dist: f32,
}

impl VisiblePoint {
    fn none() -> Self {
        VisiblePoint {
            live: false,
            p: Vec3::ZERO,
            frame: Frame::from_normal(Vec3::Z),
            wo: Vec3::Z,
            bsdf: ShadingBsdf::new(),
            beta: Spectrum::ZERO,
            depth: 0,
            dist: 0.0,
        }
    }

    /// The point, if the pixel has one this iteration.
    #[inline]
    fn get(&self) -> Option<&Self> {
        self.live.then_some(self)
    }
}

/// One photon's deposit: pixel, β f.
type Deposit = (u32, Spectrum);

/// Photons per work chunk (the unit of parallelism and of the fixed summation order).
const PHOTON_CHUNK: u64 = 2048;

/// The automatic initial radius, in pixel footprints at the visible point (see the module
/// documentation for why one).
const FOOTPRINTS: f64 = 1.0;

/// Key of the photons' sample streams, apart from the camera's.
const PHOTON_STREAM: u64 = 0x9e07_0a55;

/// The grid's cells: cubes of side 1 / `inv_cell` from `origin`, hashed into `buckets`.
#[derive(Clone, Copy, Default)]
struct Lattice {
    origin: Vec3,
    inv_cell: f32,
    buckets: usize,
}

impl Lattice {
    fn cell(&self, p: Vec3) -> [i32; 3] {
        let c = ((p - self.origin) * self.inv_cell).floor();
        [c.x as i32, c.y as i32, c.z as i32]
    }

    fn bucket(&self, c: [i32; 3]) -> usize {
        let h = (c[0] as u32 as u64).wrapping_mul(73_856_093)
            ^ (c[1] as u32 as u64).wrapping_mul(19_349_663)
            ^ (c[2] as u32 as u64).wrapping_mul(83_492_791);
        (h % self.buckets as u64) as usize
    }

    /// Calls `f(point, bucket)` for every bucket of every point's cells, in point order.
    fn for_each_bucket(&self, vps: &[VisiblePoint], radius: &[f64], mut f: impl FnMut(u32, usize)) {
        for (i, (vp, &r)) in vps.iter().zip(radius).enumerate() {
            let Some(vp) = vp.get() else { continue };
            let (a, b) = (
                self.cell(vp.p - Vec3::splat(r as f32)),
                self.cell(vp.p + Vec3::splat(r as f32)),
            );
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        f(i as u32, self.bucket([x, y, z]));
                    }
                }
            }
        }
    }
}

/// A spatial hash grid over the visible points: every point is listed in each cell its
/// gather sphere overlaps. The buckets are one flat array sorted by bucket (a counting sort,
/// points in index order within a bucket), rebuilt in place each iteration.
#[derive(Default)]
struct Grid {
    lattice: Lattice,
    /// Bucket b lists `entries[start[b]..start[b + 1]]`.
    start: Vec<u32>,
    entries: Vec<u32>,
    /// The last point counted in each bucket, so that a point whose cells collide in a
    /// bucket is listed there once.
    last: Vec<u32>,
    /// Each bucket's next free entry while placing.
    next: Vec<u32>,
}

impl Grid {
    /// Rebuilds the grid over this iteration's visible points; false when there are none
    /// (or no positive radius).
    fn rebuild(&mut self, vps: &[VisiblePoint], radius: &[f64]) -> bool {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut max_r = 0.0f32;
        let mut count = 0;
        for (vp, &r) in vps.iter().zip(radius) {
            if let Some(vp) = vp.get() {
                lo = lo.min(vp.p - Vec3::splat(r as f32));
                max_r = max_r.max(r as f32);
                count += 1;
            }
        }
        if count == 0 || max_r <= 0.0 || !lo.is_finite() {
            return false;
        }
        let n = count * 2;
        let lattice = Lattice {
            origin: lo,
            inv_cell: 1.0 / max_r,
            buckets: n,
        };
        self.lattice = lattice;
        // Count, then place: bucket sizes, their prefix sums, then the entries.
        self.start.clear();
        self.start.resize(n + 1, 0);
        self.last.clear();
        self.last.resize(n, u32::MAX);
        lattice.for_each_bucket(vps, radius, |i, b| {
            if self.last[b] != i {
                self.last[b] = i;
                self.start[b + 1] += 1;
            }
        });
        for b in 0..n {
            self.start[b + 1] += self.start[b];
        }
        self.entries.clear();
        self.entries.resize(self.start[n] as usize, 0);
        self.last.fill(u32::MAX);
        self.next.clear();
        self.next.extend_from_slice(&self.start[..n]);
        lattice.for_each_bucket(vps, radius, |i, b| {
            if self.last[b] != i {
                self.last[b] = i;
                self.entries[self.next[b] as usize] = i;
                self.next[b] += 1;
            }
        });
        true
    }

    fn candidates(&self, p: Vec3) -> &[u32] {
        let b = self.lattice.bucket(self.lattice.cell(p));
        &self.entries[self.start[b] as usize..self.start[b + 1] as usize]
    }
}

/// The progressive radius reduction of Hachisuka and Jensen (2009, eqs. 6-8; pbrt-v4
/// §15.1.5): a pixel with `n` accumulated photons, gather radius `r` and flux `tau` that
/// found `m` photons of flux `phi` (times its camera throughput) in this iteration keeps
/// the share α of them: N' = N + α M, r' = r √(N' / (N + M)), τ' = (τ + Φ) r'² / r².
pub fn update(
    n: f64,
    r: f64,
    tau: glam::DVec3,
    m: u64,
    phi: glam::DVec3,
    alpha: f64,
) -> (f64, f64, glam::DVec3) {
    let n_new = n + alpha * m as f64;
    let r_new = r * (n_new / (n + m as f64)).sqrt();
    (n_new, r_new, (tau + phi) * (r_new * r_new) / (r * r))
}

impl Sppm {
    /// Step 1 for one pixel: the emission seen and the direct lighting at the visible
    /// point, times the throughput; the visible point goes to `vp` (not `live` without one),
    /// whose BSDF is the scratch BSDF of every vertex on the way.
    fn camera_path(
        &self,
        scene: &Scene,
        pos: Vec2,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
        vp: &mut VisiblePoint,
    ) -> Spectrum {
        let mut ld = Spectrum::ZERO;
        vp.live = false;
        let res = Vec2::new(scene.width as f32, scene.height as f32);
        let mut ray = if scene.camera.needs_aperture_sample() {
            let u = sampler.next_2d();
            scene.camera.generate_ray_lens(pos / res, u)
        } else {
            scene.camera.generate_ray(pos / res)
        };
        let mut beta = Spectrum::ONE;
        let mut dist = 0.0f32;
        // Segments so far, counting the one being traced.
        let mut depth = 1u32;
        // The share of the emission at the next hit this path carries (below 1 after a split
        // delta bounce, whose other branch was added already).
        let mut emission_share = 1.0f32;
        while depth <= self.max_depth {
            stats.rays += 1;
            let hit = scene.intersect(&ray);
            // Emission is seen directly or through delta bounces only (what follows the
            // visible point is the photons' and the direct-light sample's).
            ld += beta * emission_share * emission_at(scene, hit.as_ref(), ray.d, NO_WAVELENGTHS);
            let Some(si) = hit else { break };
            stats.bounces += 1;
            dist += si.t * ray.d.length();
            scene.shading_bsdf_into(&si, NO_WAVELENGTHS, &mut vp.bsdf);
            let bsdf = &vp.bsdf;
            let wo = si.frame.to_local(-ray.d.normalize());
            let u_light = sampler.next_2d();
            if bsdf.has_smooth_lobe(wo) {
                if depth < self.max_depth {
                    if let Some(e) =
                        sample_emitter(scene, &si, bsdf, wo, u_light, NO_WAVELENGTHS, stats)
                    {
                        ld += beta * e.value;
                    }
                }
                vp.live = true;
                vp.p = si.p;
                vp.frame = si.frame;
                vp.wo = wo;
                vp.beta = beta;
                vp.depth = depth;
                vp.dist = dist;
                break;
            }
            let (u1, u2) = (sampler.next_1d(), sampler.next_2d());
            let Some(bs) = bsdf.sample(wo, u1, u2) else {
                break;
            };
            emission_share = if depth < self.max_depth {
                self.split_emission(scene, &si, bsdf, wo, &bs, beta, &mut ld, stats)
            } else {
                1.0
            };
            beta *= bs.weight;
            if !beta.is_finite() || beta.max_element() <= 0.0 {
                break;
            }
            ray = Scene::spawn_ray(&si, si.frame.to_world(bs.wo));
            depth += 1;
        }
        ld
    }

    /// Splitting (Arvo and Kirk 1990) of the emission seen past a glass surface. Where the
    /// BSDF picked one of two delta lobes at random (a smooth `dielectric` or
    /// `thindielectric`: reflection with probability F, weight w_r; transmission with 1 − F,
    /// weight w_t), the emission at the next hit of both lobes is counted exactly,
    /// β (F w_r L_r + (1 − F) w_t L_t): the other lobe's by one more ray here, the picked
    /// lobe's at the continuing path's next hit, scaled by the returned share (its
    /// probability; 1 without a split). Emission further along stays sampled as before, so
    /// the expectation is unchanged and the variance of the pick is gone from what is seen
    /// next. On `scenes/caustic-glass.xml` the light's reflection in the sphere, picked with
    /// F ≈ 4% and then worth 400, had a per-sample variance of ~290 in its brightest pixel
    /// and decided the image's error (docs/light-paths.md); split, each such sample is worth
    /// F · 400 ≈ 17.
    #[allow(clippy::too_many_arguments)]
    fn split_emission(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        bsdf: &ShadingBsdf,
        wo: Vec3,
        sampled: &BsdfSample,
        beta: Spectrum,
        ld: &mut Spectrum,
        stats: &mut PathStats,
    ) -> f32 {
        let Some(branches) = bsdf.delta_branches(wo) else {
            return 1.0;
        };
        // The picked lobe among them (always there: `branches` lists `sample`'s outcomes;
        // without it, no split). A single branch (total internal reflection) has share 1.
        let Some(picked) = branches.iter().position(|b| b.wo == sampled.wo) else {
            return 1.0;
        };
        for (k, b) in branches.iter().enumerate() {
            if k != picked {
                let ray = Scene::spawn_ray(si, si.frame.to_world(b.wo));
                stats.rays += 1;
                let hit = scene.intersect(&ray);
                *ld += beta
                    * b.weight
                    * b.pdf
                    * emission_at(scene, hit.as_ref(), ray.d, NO_WAVELENGTHS);
            }
        }
        branches[picked].pdf
    }

    /// Step 2 for one photon: its deposits.
    #[allow(clippy::too_many_arguments)]
    fn trace_photon(
        &self,
        scene: &Scene,
        lights: &Distribution1D,
        vps: &[VisiblePoint],
        radius: &[f64],
        grid: &Grid,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
        deposits: &mut Vec<Deposit>,
    ) {
        let (i, _) = lights.sample_reuse(sampler.next_1d());
        let pmf = lights.pmf(i) as f32;
        let (u_pos, u_dir) = (sampler.next_2d(), sampler.next_2d());
        let Some(er) = scene.emitters[i].sample_ray(
            u_pos,
            u_dir,
            &scene.shapes,
            scene.bounding_sphere,
            NO_WAVELENGTHS,
        ) else {
            return;
        };
        let mut beta = er.weight / pmf;
        let mut ray = er.ray;
        // Surface hits so far, counting the one being looked for.
        let mut hits = 1u32;
        // Filled in place at each vertex (see `Scene::shading_bsdf_into`).
        let mut bsdf = ShadingBsdf::new();
        while hits <= self.max_depth {
            stats.rays += 1;
            let Some(si) = scene.intersect(&ray) else {
                break;
            };
            stats.bounces += 1;
            let wi_world = -ray.d.normalize();
            if hits >= 2 {
                for &k in grid.candidates(si.p) {
                    let Some(vp) = vps[k as usize].get() else {
                        continue;
                    };
                    let r = radius[k as usize] as f32;
                    if vp.depth + hits > self.max_depth || vp.p.distance_squared(si.p) > r * r {
                        continue;
                    }
                    let wi = vp.frame.to_local(wi_world);
                    if wi.z == 0.0 {
                        continue;
                    }
                    let f = vp.bsdf.eval(vp.wo, wi) / wi.z.abs();
                    let v = beta * f;
                    if v.max_element() > 0.0 && v.is_finite() {
                        deposits.push((k, v));
                    }
                }
            }
            if hits == self.max_depth {
                break;
            }
            scene.shading_bsdf_into(&si, NO_WAVELENGTHS, &mut bsdf);
            bsdf.set_importance();
            let wi = si.frame.to_local(wi_world);
            let (u1, u2) = (sampler.next_1d(), sampler.next_2d());
            let Some(bs) = bsdf.sample(wi, u1, u2) else {
                break;
            };
            let wo_world = si.frame.to_world(bs.wo);
            let Some(correction) =
                super::ptracer::adjoint_correction(si.ng, wi_world, wi, wo_world, bs.wo)
            else {
                break;
            };
            let next = beta * bs.weight * correction;
            let (l_old, l_new) = (
                crate::spectrum::luminance(beta),
                crate::spectrum::luminance(next),
            );
            if !(l_old > 0.0 && l_new > 0.0 && next.is_finite()) {
                break;
            }
            // Russian roulette: continue with probability min(1, lum(β') / lum(β)).
            let q = (l_new / l_old).min(1.0);
            if q < 1.0 && sampler.next_1d() >= q {
                stats.rr_terminated += 1;
                break;
            }
            beta = next / q;
            ray = Scene::spawn_ray(&si, wo_world);
            hits += 1;
        }
    }

    /// Renders `settings.spp` iterations from scratch (a render continued from a state
    /// goes through [`Sppm::iterate`]: `settings.first_sample` must be 0 here, since the
    /// film alone cannot continue an SPPM render).
    pub fn render(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        pool: &rayon::ThreadPool,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> crate::error::Result<RenderOutput> {
        if settings.first_sample != 0 {
            return Err(crate::error::Error::Invalid(
                "an sppm render cannot continue from a film (its per-pixel radii and photon \
                 counts are not in it): resume it from a checkpoint"
                    .into(),
            ));
        }
        let mut state = SppmState::new(scene, self);
        let stats = self.iterate(
            scene,
            settings,
            pool,
            &mut state,
            settings.spp as u64,
            progress,
        );
        Ok(RenderOutput {
            film: state.film(scene),
            stats,
        })
    }

    /// Runs `count` more iterations on `state` (numbered on from `state.iterations`, so that
    /// a render continued from a saved state is bit-identical to one run straight through),
    /// with `settings`' seed, sampler and threads; returns their statistics.
    pub fn iterate(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        pool: &rayon::ThreadPool,
        state: &mut SppmState,
        count: u64,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> RenderStats {
        let (w, h) = (scene.width, scene.height);
        let n = w * h;
        let start = Instant::now();
        let mut stats = RenderStats {
            paths: n as u64 * count,
            ..Default::default()
        };
        let lights = Distribution1D::new(scene.emitters.iter().map(|e| {
            e.power(&scene.shapes, scene.bounding_sphere.1 as f64)
                .max(0.0)
        }));
        let SppmState {
            iterations,
            photons_emitted,
            ld,
            big_n,
            tau,
            radius,
        } = state;
        // The pixel's angular size, for the automatic initial radius.
        let pixel_angle = {
            let a = scene.camera.generate_ray(Vec2::splat(0.5)).d.normalize();
            let b = scene
                .camera
                .generate_ray(Vec2::new(0.5 + 1.0 / w as f32, 0.5))
                .d
                .normalize();
            a.dot(b).clamp(-1.0, 1.0).acos().max(1e-6) as f64
        };
        let sampler = settings.sampler.unwrap_or(scene.sampler);
        let total = n as u64 * count;
        let first = *iterations;
        // Buffers reused by every iteration (a visible point holds a whole BSDF: moving
        // them around each iteration cost more than tracing them).
        let mut vps: Vec<VisiblePoint> = vec![VisiblePoint::none(); n];
        let mut lds = vec![Spectrum::ZERO; n];
        let mut row_stats = vec![PathStats::default(); h];
        let mut grid = Grid::default();
        let mut phi = vec![glam::DVec3::ZERO; n];
        let mut m = vec![0u64; n];
        for iteration in first..first + count {
            // 1. Camera pass, by rows.
            pool.install(|| {
                vps.par_chunks_mut(w)
                    .zip(lds.par_chunks_mut(w))
                    .zip(row_stats.par_iter_mut())
                    .enumerate()
                    .for_each(|(y, ((vp_row, ld_row), st))| {
                        *st = PathStats::default();
                        for (x, (vp, l)) in vp_row.iter_mut().zip(ld_row).enumerate() {
                            let (pixel, size) = scene.sample_key(x as i64, y as i64);
                            let mut s = sampler.stream(settings.seed, pixel, size, iteration);
                            let pos = Vec2::new(x as f32, y as f32) + s.next_2d();
                            *l = self.camera_path(scene, pos, &mut s, st, vp);
                        }
                    })
            });
            for st in &row_stats {
                stats.path += *st;
            }
            for i in 0..n {
                if lds[i].is_finite() {
                    ld[i] += to_rgb(lds[i]).as_dvec3();
                } else {
                    stats.nonfinite += 1;
                }
                if let Some(vp) = vps[i].get() {
                    if radius[i] <= 0.0 {
                        radius[i] = (FOOTPRINTS * vp.dist as f64 * pixel_angle).max(1e-6);
                    }
                }
            }
            // 2. Photon pass.
            phi.fill(glam::DVec3::ZERO);
            m.fill(0);
            if let Some(lights) = lights.as_ref().filter(|_| grid.rebuild(&vps, radius)) {
                let chunks = self.photon_count.div_ceil(PHOTON_CHUNK);
                let results: Vec<(Vec<Deposit>, PathStats)> = pool.install(|| {
                    (0..chunks)
                        .into_par_iter()
                        .map(|c| {
                            let mut deposits = Vec::new();
                            let mut st = PathStats::default();
                            let end = ((c + 1) * PHOTON_CHUNK).min(self.photon_count);
                            for j in c * PHOTON_CHUNK..end {
                                let mut s =
                                    SampleStream::new(settings.seed ^ PHOTON_STREAM, iteration, j);
                                self.trace_photon(
                                    scene,
                                    lights,
                                    &vps,
                                    radius,
                                    &grid,
                                    &mut s,
                                    &mut st,
                                    &mut deposits,
                                );
                            }
                            (deposits, st)
                        })
                        .collect()
                });
                for (deposits, st) in results {
                    stats.path += st;
                    for (k, v) in deposits {
                        phi[k as usize] += to_rgb(v).as_dvec3();
                        m[k as usize] += 1;
                    }
                }
                *photons_emitted += self.photon_count;
            }
            // 3. Update.
            for i in 0..n {
                if m[i] == 0 {
                    continue;
                }
                let Some(vp) = vps[i].get() else { continue };
                (big_n[i], radius[i], tau[i]) = update(
                    big_n[i],
                    radius[i],
                    tau[i],
                    m[i],
                    to_rgb(vp.beta).as_dvec3() * phi[i],
                    self.alpha as f64,
                );
            }
            progress((iteration + 1 - first) * n as u64, total);
        }
        *iterations += count;
        stats.seconds = start.elapsed().as_secs_f64();
        stats
    }
}

/// An SPPM render's running state: per pixel the summed direct part L_d, the photon count N,
/// the flux τ and the radius, with the iterations run and the photons emitted. Enough to
/// continue the render (checkpoints save it) and to make its image ([`SppmState::film`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SppmState {
    pub iterations: u64,
    pub photons_emitted: u64,
    pub ld: Vec<glam::DVec3>,
    pub big_n: Vec<f64>,
    pub tau: Vec<glam::DVec3>,
    /// 0 until the pixel's first visible point when the radius is automatic.
    pub radius: Vec<f64>,
}

impl SppmState {
    /// The state before the first iteration.
    pub fn new(scene: &Scene, sppm: &Sppm) -> Self {
        let n = scene.width * scene.height;
        SppmState {
            iterations: 0,
            photons_emitted: 0,
            ld: vec![glam::DVec3::ZERO; n],
            big_n: vec![0.0; n],
            tau: vec![glam::DVec3::ZERO; n],
            radius: vec![sppm.initial_radius as f64; n],
        }
    }

    /// The image so far, as a film of k samples per pixel of value L each (k the
    /// iterations): L = L_d / k + τ / (N_e π r²). Its variance channels are zero (a pixel
    /// is not a mean of independent samples).
    pub fn film(&self, scene: &Scene) -> Film {
        let n = scene.width * scene.height;
        let mut film = Film::new(scene.width, scene.height, scene.filter);
        let k = self.iterations as f64;
        for i in 0..n.min(self.ld.len()) {
            let mut l = self.ld[i] / k.max(1.0);
            if self.photons_emitted > 0 && self.radius[i] > 0.0 {
                l += self.tau[i]
                    / (self.photons_emitted as f64
                        * std::f64::consts::PI
                        * self.radius[i]
                        * self.radius[i]);
            }
            for (c, l) in [l.x, l.y, l.z].into_iter().enumerate() {
                film.sum[i][c] = l * k;
                film.sum_sq[i][c] = l * l * k;
                film.sum_w2[i][c] = l * k;
                film.sum_sq_w2[i][c] = l * l * k;
            }
            film.weight[i] = k;
            film.weight_sq[i] = k;
            film.weight_cube[i] = k;
        }
        film.samples = n as u64 * self.iterations;
        film
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// The hash grid lists, for any point, every visible point whose gather sphere holds it
    /// (checked against brute force), each once and in index order; rebuilt in place over a
    /// second set of points, it forgets the first.
    #[test]
    fn grid_candidates_hold_every_point_in_reach_once() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut grid = Grid::default();
        for (count, r_max) in [(400usize, 0.15f64), (300, 0.1)] {
            let vps: Vec<VisiblePoint> = (0..count)
                .map(|_| VisiblePoint {
                    live: rng.random::<f32>() < 0.9,
                    p: Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - 1.0,
                    ..VisiblePoint::none()
                })
                .collect();
            let radius: Vec<f64> = (0..count)
                .map(|_| r_max * (0.1 + 0.9 * rng.random::<f64>()))
                .collect();
            assert!(grid.rebuild(&vps, &radius));
            let mut found = 0;
            for _ in 0..20_000 {
                let q = Vec3::new(rng.random(), rng.random(), rng.random()) * 2.4 - 1.2;
                let c = grid.candidates(q);
                assert!(c.windows(2).all(|w| w[0] < w[1]), "{c:?}");
                for (i, (vp, &r)) in vps.iter().zip(&radius).enumerate() {
                    let Some(vp) = vp.get() else {
                        assert!(!c.contains(&(i as u32)));
                        continue;
                    };
                    if vp.p.distance(q) <= r as f32 {
                        found += 1;
                        assert!(c.contains(&(i as u32)), "point {i} missing at {q}");
                    }
                }
            }
            assert!(found > 100, "{found} points in reach: too few to test");
        }
        assert!(!grid.rebuild(&[VisiblePoint::none(), VisiblePoint::none()], &[0.1, 0.1]));
    }

    /// A grid needs a positive, finite cell size and a finite corner: a live point whose
    /// radius is 0 or +inf (cell size 1/0 or 1/inf) is refused, not hashed into a lattice
    /// whose cell coordinates come out inf or NaN.
    #[test]
    fn grid_refuses_radii_it_cannot_index() {
        let live = || VisiblePoint {
            live: true,
            p: Vec3::new(0.5, -1.0, 2.0),
            ..VisiblePoint::none()
        };
        let mut grid = Grid::default();
        assert!(grid.rebuild(&[live()], &[0.1]));
        for r in [0.0, f64::INFINITY] {
            assert!(!grid.rebuild(&[live()], &[r]), "radius {r} accepted");
        }
    }

    /// The update's arithmetic on hand-computed cases: the first iteration (N = 0) keeps α M
    /// photons and shrinks the area by α; a pixel that keeps finding the same photon
    /// density keeps the same density estimate τ / (N_e π r²) up to the N_e growth.
    #[test]
    fn radius_reduction_follows_hachisuka_and_jensen() {
        let (n, r, tau) = update(0.0, 2.0, DVec3::ZERO, 30, DVec3::splat(6.0), 2.0 / 3.0);
        assert!((n - 20.0).abs() < 1e-12);
        assert!((r * r - 4.0 * 2.0 / 3.0).abs() < 1e-12, "{r}");
        assert!((tau - DVec3::splat(6.0 * 2.0 / 3.0)).abs().max_element() < 1e-12);
        // N = 20, r² = 8/3, M = 10: N' = 20 + 20/3, r'² = r² (80/3) / 30.
        let (n2, r2, tau2) = update(n, r, tau, 10, DVec3::new(1.0, 2.0, 3.0), 2.0 / 3.0);
        assert!((n2 - 80.0 / 3.0).abs() < 1e-12);
        let ratio = (80.0 / 3.0) / 30.0;
        assert!((r2 * r2 - 8.0 / 3.0 * ratio).abs() < 1e-12);
        let want = (DVec3::splat(4.0) + DVec3::new(1.0, 2.0, 3.0)) * ratio;
        assert!((tau2 - want).abs().max_element() < 1e-12, "{tau2}");
        // α → 1 keeps every photon and the radius.
        let (_, r3, _) = update(5.0, 1.5, DVec3::ONE, 7, DVec3::ONE, 1.0);
        assert!((r3 - 1.5).abs() < 1e-15);
    }
}
