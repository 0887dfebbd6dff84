//! `radiosity`: the finite-element method for diffuse interreflection (Goral, Torrance,
//! Greenberg and Battaile 1984, "Modeling the Interaction of Light Between Diffuse
//! Surfaces"), solved by progressive refinement (Cohen, Chen, Wallace and Greenberg 1988,
//! "A Progressive Refinement Approach to Fast Radiosity Image Generation"); penumbra's own
//! (Mitsuba 3 has none).
//!
//! 1. **Meshing.** Every surface is divided into patches of about equal area: each triangle
//!    of a mesh into k² congruent triangles (k from the target patch area or edge length),
//!    each sphere into cells of equal area (bands of equal height in z — Archimedes — times
//!    sectors of equal angle). A patch has a front and a back side; a side becomes a patch of
//!    the solution where it reflects (diffuse reflectance ρ > 0) or emits. ρ and the
//!    exitance E = π L_e are averaged over the form-factor ray origins of the patch, so
//!    textured reflectance and emission enter as their patch averages.
//! 2. **Form factors** by Monte Carlo ray casting with visibility: from `rays_per_patch`
//!    points uniform on patch i, cosine-distributed directions; the share of rays whose
//!    first hit is (the facing side of) patch j estimates F_ij without bias (the ray's
//!    cosine density is the form factor's kernel). Rays that leave the scene, or hit a side
//!    that neither reflects nor emits, carry energy out of the system.
//! 3. **Progressive refinement (shooting):** every patch starts with B = U = E (U: unshot
//!    radiosity); a patch shoots its unshot power to all others,
//!    ΔB_j = ρ_j U_i F_ij A_i / A_j, and its U becomes 0. Shooting runs in sweeps, each
//!    shooting every patch in order of decreasing unshot power A·U (Cohen et al. pick the
//!    single largest before every shot; sweeps avoid that O(n) search per shot and converge
//!    in the same way), until the unshot power is below `residual` times the emitted power.
//! 4. **The image**, `shading`: `flat` shows each patch's radiance B/π as it is (the classic
//!    faceted look: bias at every patch edge); `gather` (the default) is a final gather at
//!    the pixel: the emission seen, direct light by one emitter sample, and one
//!    cosine-distributed ray whose hit contributes the reflected part (B − E)/π of its
//!    patch, weighted by the exact reflectance at the pixel. The bias of `gather` is that of
//!    the patch solution one bounce away, so it falls much faster with the patch count.
//!
//! What it represents: diffuse surfaces (`diffuse`, or `twosided` of diffuse BSDFs; textures
//! allowed), meshes and spheres, area lights. Anything else — other BSDFs, point, spot,
//! directional and environment lights, disks, cylinders, SDF grids, instances, media — is
//! refused with one line when the scene is built, instead of being approximated silently.
//!
//! The form-factor rays are seeded by the render's seed: renders with different seeds have
//! independent solutions, so the spread of a convergence study over seeds includes the
//! solution's noise. A render's time includes its solve (the first render with a seed); the
//! solution is kept for further renders with the same seed.

use crate::bsdf::{Bsdf, Spectrum};
use crate::emitter::Emitter;
use crate::error::{Error, Result};
use crate::geometry::Ray;
use crate::integrator::{emission_at, sample_emitter, PathStats};
use crate::material::Material;
use crate::sampler::SampleStream;
use crate::sampling::{square_to_cosine_hemisphere, square_to_uniform_triangle};
pub use crate::scene::description::{RadiosityParams, Shading};
use crate::scene::Scene;
use crate::shape::{ShapeGeometry, SurfaceInteraction};
use crate::spectrum::NO_WAVELENGTHS;
use glam::{Vec2, Vec3};
use rand::RngExt;
use rayon::prelude::*;
use std::f64::consts::PI as PI64;
use std::sync::{Arc, RwLock};

// The form-factor rays a scene may ask for in all (2 sides × patches × `rays_per_patch`) are
// the `radiosity_rays` limit of `crate::limits` (default 2^28, about a minute of ray casting
// here; the ladder's finest study, 16,384 patches × 1,024 rays × 2, casts 2^25). Refused when
// the scene is read if `patch_count` alone exceeds it, else once the patches are made.
/// Geometric patches (cells) a scene may be divided into.
pub const MAX_CELLS: u64 = 1 << 22;
/// Shooting sweeps before giving up on the residual (reflectance 1 in a closed scene never
/// converges); the residual reached is kept in [`Solution::residual`].
pub const MAX_SWEEPS: u32 = 256;

/// How one shape is divided into cells.
#[derive(Clone, Debug)]
enum ShapeCells {
    /// Triangle t is divided into k[t]² triangles, cells first[t] .. first[t] + k[t]².
    Mesh { k: Vec<u32>, first: Vec<u32> },
    /// `nz` bands of equal height times `nphi` sectors; band-major from the pole at +z.
    Sphere { nz: u32, nphi: u32, first: u32 },
}

/// The geometry of one cell.
#[derive(Clone, Copy, Debug)]
enum CellGeom {
    /// A sub-triangle of triangle `prim`, by the barycentrics (b1, b2) of its corners.
    Triangle { prim: u32, corners: [Vec2; 3] },
    /// z ∈ [z0, z1] and φ ∈ [φ0, φ1] in the sphere's frame.
    SphereCell { z: [f64; 2], phi: [f64; 2] },
}

#[derive(Clone, Copy, Debug)]
struct Cell {
    shape: u32,
    area: f64,
    geom: CellGeom,
}

/// The division of a scene's surfaces into cells (geometric patches): fixed by the scene
/// and the parameters, independent of the seed.
#[derive(Clone, Debug)]
pub struct Layout {
    shapes: Vec<ShapeCells>,
    cells: Vec<Cell>,
}

/// `Ok` when material `m` is diffuse (or two-sided diffuse), else the plugin that is not.
fn check_diffuse(materials: &[Material], m: u32) -> std::result::Result<(), &'static str> {
    match materials.get(m as usize) {
        Some(Material::Leaf {
            template: Bsdf::Diffuse(_),
            ..
        }) => Ok(()),
        Some(Material::TwoSided { front, back }) => {
            check_diffuse(materials, *front)?;
            check_diffuse(materials, *back)
        }
        Some(other) => Err(other.plugin_name()),
        None => Err("missing"),
    }
}

impl Layout {
    /// Checks that radiosity can represent `scene` (one line naming what it cannot) and
    /// divides its surfaces into cells.
    pub fn new(scene: &Scene, params: &RadiosityParams) -> Result<Layout> {
        let refuse = |what: String| {
            Err(Error::Invalid(format!(
                "radiosity represents diffuse surfaces on meshes and spheres lit by area \
                 lights only: {what} (use the path integrator)"
            )))
        };
        if !scene.media.is_empty() || scene.camera_medium.is_some() {
            return refuse("the scene has participating media".into());
        }
        if scene.accel.has_instances() {
            return refuse("the scene instances shape groups".into());
        }
        for e in &scene.emitters {
            if !matches!(e, Emitter::Area(_)) {
                return refuse(format!("the scene has a {} emitter", e.plugin_name()));
            }
        }
        for (i, shape) in scene.shapes.iter().enumerate() {
            if !matches!(
                shape.geometry,
                ShapeGeometry::Mesh(_) | ShapeGeometry::Sphere(_)
            ) {
                return refuse(format!("shape {i} is a {}", shape.geometry.plugin_name()));
            }
            if let Err(name) = check_diffuse(&scene.materials, shape.material) {
                return refuse(format!("shape {i} has a '{name}' BSDF"));
            }
        }
        let total_area: f64 = scene.shapes.iter().map(|s| s.geometry.area()).sum();
        if !(total_area > 0.0 && total_area.is_finite()) {
            return Err(Error::Invalid(
                "radiosity: the scene has no surface to divide into patches".into(),
            ));
        }
        let size = params.patch_size as f64;
        let cell_area = if size > 0.0 {
            size * size
        } else {
            total_area / params.patch_count.max(1) as f64
        };
        let too_many = || {
            Error::Invalid(format!(
                "radiosity: more than {MAX_CELLS} patches (increase patch_size or lower \
                 patch_count)"
            ))
        };
        let mut cells: Vec<Cell> = Vec::new();
        let mut shapes = Vec::with_capacity(scene.shapes.len());
        for (s, shape) in scene.shapes.iter().enumerate() {
            let s32 = s as u32;
            match &shape.geometry {
                ShapeGeometry::Mesh(m) => {
                    let n = m.triangles.len();
                    let (mut ks, mut first) = (Vec::with_capacity(n), Vec::with_capacity(n));
                    for t in 0..n {
                        let area = m.triangle_area(t);
                        let [p0, p1, p2] = m.vertices(t);
                        let edge = (p1 - p0)
                            .length()
                            .max((p2 - p1).length())
                            .max((p0 - p2).length()) as f64;
                        let k = if size > 0.0 {
                            (edge / size).ceil()
                        } else {
                            (area / cell_area).sqrt().ceil()
                        };
                        let k = k.clamp(1.0, 4096.0) as u32;
                        if cells.len() as u64 + (k as u64).pow(2) > MAX_CELLS {
                            return Err(too_many());
                        }
                        ks.push(k);
                        first.push(cells.len() as u32);
                        let sub_area = area / (k * k) as f64;
                        let kf = k as f32;
                        for i in 0..k {
                            for j in 0..k - i {
                                let b = |a: u32, c: u32| Vec2::new(a as f32 / kf, c as f32 / kf);
                                let mut push = |corners| {
                                    cells.push(Cell {
                                        shape: s32,
                                        area: sub_area,
                                        geom: CellGeom::Triangle {
                                            prim: t as u32,
                                            corners,
                                        },
                                    })
                                };
                                push([b(i, j), b(i + 1, j), b(i, j + 1)]);
                                if i + j + 2 <= k {
                                    push([b(i + 1, j), b(i + 1, j + 1), b(i, j + 1)]);
                                }
                            }
                        }
                    }
                    shapes.push(ShapeCells::Mesh { k: ks, first });
                }
                ShapeGeometry::Sphere(sphere) => {
                    let nz = if size > 0.0 {
                        (PI64 * sphere.radius / size).ceil()
                    } else {
                        (sphere.area() / cell_area / 2.0).sqrt().ceil()
                    }
                    .clamp(1.0, 2048.0) as u32;
                    let nphi = 2 * nz;
                    if cells.len() as u64 + (nz * nphi) as u64 > MAX_CELLS {
                        return Err(too_many());
                    }
                    let first = cells.len() as u32;
                    let area = sphere.area() / (nz * nphi) as f64;
                    for iz in 0..nz {
                        let z1 = 1.0 - 2.0 * iz as f64 / nz as f64;
                        let z0 = 1.0 - 2.0 * (iz + 1) as f64 / nz as f64;
                        for ip in 0..nphi {
                            let phi0 = 2.0 * PI64 * ip as f64 / nphi as f64;
                            let phi1 = 2.0 * PI64 * (ip + 1) as f64 / nphi as f64;
                            cells.push(Cell {
                                shape: s32,
                                area,
                                geom: CellGeom::SphereCell {
                                    z: [z0, z1],
                                    phi: [phi0, phi1],
                                },
                            });
                        }
                    }
                    shapes.push(ShapeCells::Sphere { nz, nphi, first });
                }
                _ => unreachable!("refused above"),
            }
        }
        // Both sides may become patches.
        let limits = crate::limits::current()?;
        let limit = crate::limits::Limit::RadiosityRays;
        let rays = 2 * cells.len() as u64 * params.rays_per_patch as u64;
        if rays > limits.radiosity_rays {
            let lower = if size > 0.0 {
                "increase patch_size or lower rays_per_patch"
            } else {
                "lower patch_count or rays_per_patch"
            };
            return Err(Error::Invalid(format!(
                "radiosity: {} patches x 2 sides x {} rays_per_patch is {rays} form-factor \
                 rays, more than {} ({lower}, or raise it with {})",
                cells.len(),
                params.rays_per_patch,
                limit.of(limits.radiosity_rays),
                limit.setting()
            )));
        }
        Ok(Layout { shapes, cells })
    }

    /// Number of cells (geometric patches).
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// The shape cell `c` lies on.
    pub fn cell_shape(&self, c: u32) -> u32 {
        self.cells[c as usize].shape
    }

    /// The cell holding the surface point `si`.
    pub fn cell_at(&self, si: &SurfaceInteraction) -> Option<u32> {
        match self.shapes.get(si.shape as usize)? {
            ShapeCells::Mesh { k, first } => {
                let t = si.prim as usize;
                let k = *k.get(t)?;
                let kf = k as f32;
                let (x, y) = (si.bary.x * kf, si.bary.y * kf);
                let i = (x.floor().max(0.0) as u32).min(k - 1);
                let j = (y.floor().max(0.0) as u32).min(k - 1 - i);
                let down = (x - i as f32) + (y - j as f32) > 1.0 && i + j + 2 <= k;
                // Row i holds 2(k − i) − 1 cells (up and down alternating).
                let row = 2 * k * i - i * i;
                Some(first[t] + row + 2 * j + down as u32)
            }
            ShapeCells::Sphere { nz, nphi, first } => {
                let z = crate::math::sin_cosf(std::f32::consts::PI * si.uv.y).1;
                let iz = (((1.0 - z) * 0.5 * *nz as f32) as u32).min(nz - 1);
                let ip = ((si.uv.x * *nphi as f32).max(0.0) as u32).min(nphi - 1);
                Some(first + iz * nphi + ip)
            }
        }
    }

    /// The surface point of cell `c` at `u` (uniform by area over the cell).
    fn sample(&self, scene: &Scene, c: usize, u: Vec2) -> SurfaceInteraction {
        let cell = &self.cells[c];
        match (&cell.geom, &scene.shapes[cell.shape as usize].geometry) {
            (CellGeom::Triangle { prim, corners }, ShapeGeometry::Mesh(m)) => {
                let b = square_to_uniform_triangle(u);
                let p = corners[0] * (1.0 - b.x - b.y) + corners[1] * b.x + corners[2] * b.y;
                m.interaction(*prim as usize, 0.0, p.x, p.y, cell.shape)
            }
            (CellGeom::SphereCell { z, phi }, ShapeGeometry::Sphere(s)) => {
                let zz = z[0] + (z[1] - z[0]) * u.x as f64;
                let ph = phi[0] + (phi[1] - phi[0]) * u.y as f64;
                let uv = Vec2::new(
                    (ph / (2.0 * PI64)) as f32,
                    (crate::math::acos(zz.clamp(-1.0, 1.0)) / PI64) as f32,
                );
                s.at_uv(uv, cell.shape)
            }
            _ => unreachable!("cells are made from their shape"),
        }
    }
}

/// One side of a cell that reflects or emits: a patch of the solution.
#[derive(Clone, Copy, Debug)]
pub struct Patch {
    pub cell: u32,
    /// 0: the side the shading normal points to; 1: the other.
    pub side: u8,
    pub area: f64,
    /// Diffuse reflectance, averaged over the patch.
    pub reflectance: Spectrum,
    /// Emitted radiosity (exitance) E = π L_e, averaged over the patch.
    pub emission: Spectrum,
}

/// A solved radiosity system.
#[derive(Debug)]
pub struct Solution {
    pub seed: u64,
    pub patches: Vec<Patch>,
    /// Per cell, the patch of each side (`u32::MAX`: that side neither reflects nor emits).
    pub cell_patch: Vec<[u32; 2]>,
    /// Row i: (j, F_ij) for every patch j that a ray from i reached first.
    pub form_factors: Vec<Vec<(u32, f32)>>,
    /// Radiosity B of each patch (exitance: emitted plus reflected).
    pub radiosity: Vec<Spectrum>,
    /// Patches shot, and the unshot share of the emitted power when shooting stopped.
    pub shots: u64,
    pub residual: f64,
}

const NONE: u32 = u32::MAX;

/// The side of the surface at `si` that a ray of direction `d` arrives at (0: the front).
fn arriving_side(si: &SurfaceInteraction, d: Vec3) -> u8 {
    (si.frame.n.dot(d) > 0.0) as u8
}

/// Generator of form-factor ray `k`'s numbers for `(seed, cell, side)`.
fn rng(seed: u64, cell: usize, side: u8) -> rand_pcg::Pcg32 {
    rand_pcg::Pcg32::new(
        seed ^ 0x9e37_79b9_7f4a_7c15,
        ((cell as u64) << 1) | side as u64,
    )
}

/// The mean of the three channels: a patch's power for the shooting order (not a
/// luminance: the order only needs a measure that is positive where any channel is).
fn channel_mean(s: Spectrum) -> f64 {
    (s.x as f64 + s.y as f64 + s.z as f64) / 3.0
}

impl Solution {
    /// The patch a ray of direction `d` sees at `si`.
    pub fn patch_seen(&self, layout: &Layout, si: &SurfaceInteraction, d: Vec3) -> Option<u32> {
        let c = layout.cell_at(si)?;
        let p = self.cell_patch.get(c as usize)?[arriving_side(si, d) as usize];
        (p != NONE).then_some(p)
    }

    /// Meshes, casts the form-factor rays and shoots to the residual.
    pub fn solve(scene: &Scene, layout: &Layout, params: &RadiosityParams, seed: u64) -> Self {
        let n_rays = params.rays_per_patch.max(1) as usize;
        // Reflectance and emission of both sides of every cell, averaged over the points
        // its form-factor rays start from.
        let sides: Vec<[(Spectrum, Spectrum); 2]> = (0..layout.cells.len())
            .into_par_iter()
            .map(|c| {
                let mut out = [(Spectrum::ZERO, Spectrum::ZERO); 2];
                let emitter = scene.shapes[layout.cells[c].shape as usize].emitter;
                for side in 0..2u8 {
                    let mut rng = rng(seed, c, side);
                    let (mut rho, mut e) = (Spectrum::ZERO, Spectrum::ZERO);
                    let z = if side == 0 { Vec3::Z } else { -Vec3::Z };
                    for _ in 0..n_rays {
                        let u = Vec2::new(rng.random(), rng.random());
                        // The direction's numbers, drawn to stay in step with the
                        // form-factor pass below (same points).
                        let _ = (rng.random::<f32>(), rng.random::<f32>());
                        let si = layout.sample(scene, c, u);
                        let bsdf = scene.shading_bsdf(&si, NO_WAVELENGTHS);
                        rho += bsdf.eval(z, z) * std::f32::consts::PI;
                        if let Some(Emitter::Area(a)) = emitter.map(|e| &scene.emitters[e as usize])
                        {
                            e += a.eval(&si, si.frame.to_world(z), &scene.shapes, NO_WAVELENGTHS)
                                * std::f32::consts::PI;
                        }
                    }
                    out[side as usize] = (rho / n_rays as f32, e / n_rays as f32);
                }
                out
            })
            .collect();
        let mut patches = Vec::new();
        let mut cell_patch = vec![[NONE; 2]; layout.cells.len()];
        for (c, s) in sides.iter().enumerate() {
            for side in 0..2u8 {
                let (rho, e) = s[side as usize];
                if rho.max_element() > 0.0 || e.max_element() > 0.0 {
                    cell_patch[c][side as usize] = patches.len() as u32;
                    patches.push(Patch {
                        cell: c as u32,
                        side,
                        area: layout.cells[c].area,
                        reflectance: rho,
                        emission: e,
                    });
                }
            }
        }
        // Form factors: the same points as above, cosine-distributed directions.
        let form_factors: Vec<Vec<(u32, f32)>> = patches
            .par_iter()
            .map(|p| {
                let mut rng = rng(seed, p.cell as usize, p.side);
                let mut hits = Vec::with_capacity(n_rays);
                for _ in 0..n_rays {
                    let u = Vec2::new(rng.random(), rng.random());
                    let v = Vec2::new(rng.random(), rng.random());
                    let si = layout.sample(scene, p.cell as usize, u);
                    let mut local = square_to_cosine_hemisphere(v);
                    if p.side == 1 {
                        local.z = -local.z;
                    }
                    let d = si.frame.to_world(local);
                    let ray = Scene::spawn_ray(&si, d);
                    if let Some(hit) = scene.intersect(&ray) {
                        let Some(c) = layout.cell_at(&hit) else {
                            continue;
                        };
                        let j = cell_patch[c as usize][arriving_side(&hit, d) as usize];
                        if j != NONE {
                            hits.push(j);
                        }
                    }
                }
                hits.sort_unstable();
                let mut row: Vec<(u32, f32)> = Vec::new();
                for j in hits {
                    match row.last_mut() {
                        Some((last, count)) if *last == j => *count += 1.0,
                        _ => row.push((j, 1.0)),
                    }
                }
                for (_, f) in &mut row {
                    *f /= n_rays as f32;
                }
                row
            })
            .collect();

        // Progressive refinement.
        let mut radiosity: Vec<Spectrum> = patches.iter().map(|p| p.emission).collect();
        let mut unshot = radiosity.clone();
        let power = |i: usize, u: &[Spectrum]| patches[i].area * channel_mean(u[i]);
        let emitted: f64 = (0..patches.len()).map(|i| power(i, &unshot)).sum();
        let mut remaining = emitted;
        let stop = params.residual as f64 * emitted;
        let mut shots = 0u64;
        let mut order: Vec<usize> = (0..patches.len()).collect();
        for _ in 0..MAX_SWEEPS {
            if remaining <= stop || emitted <= 0.0 {
                break;
            }
            order.sort_by(|&a, &b| power(b, &unshot).total_cmp(&power(a, &unshot)));
            for &i in &order {
                let u = unshot[i];
                if u == Spectrum::ZERO {
                    continue;
                }
                unshot[i] = Spectrum::ZERO;
                shots += 1;
                let a_i = patches[i].area;
                for &(j, f) in &form_factors[i] {
                    let j = j as usize;
                    let db = patches[j].reflectance * u * (f as f64 * a_i / patches[j].area) as f32;
                    radiosity[j] += db;
                    unshot[j] += db;
                }
                if shots.is_multiple_of(1024) {
                    remaining = (0..patches.len()).map(|k| power(k, &unshot)).sum();
                    if remaining <= stop {
                        break;
                    }
                }
            }
            remaining = (0..patches.len()).map(|k| power(k, &unshot)).sum();
        }
        Solution {
            seed,
            patches,
            cell_patch,
            form_factors,
            radiosity,
            shots,
            residual: if emitted > 0.0 {
                remaining / emitted
            } else {
                0.0
            },
        }
    }
}

/// The `radiosity` integrator: its parameters, the scene's cells, and the solution of the
/// last seed rendered (shared by clones).
#[derive(Clone, Debug)]
pub struct RadiosityIntegrator {
    pub params: RadiosityParams,
    pub layout: Arc<Layout>,
    solution: Arc<RwLock<Option<Arc<Solution>>>>,
    /// The solution of the render under way, read without locking
    /// ([`RadiosityIntegrator::with_solution`]).
    fixed: Option<Arc<Solution>>,
}

impl RadiosityIntegrator {
    /// Checks that the scene can be represented and divides it into cells (one line on
    /// failure); the solve waits for the first render.
    pub fn new(scene: &Scene, params: RadiosityParams) -> Result<Self> {
        let layout = Arc::new(Layout::new(scene, &params)?);
        Ok(RadiosityIntegrator {
            params,
            layout,
            solution: Arc::new(RwLock::new(None)),
            fixed: None,
        })
    }

    /// The solution for `seed`, solved now (with the calling thread pool) unless it is the
    /// one kept from the last render.
    pub fn prepare(&self, scene: &Scene, seed: u64) -> Arc<Solution> {
        if let Some(s) = self.current().filter(|s| s.seed == seed) {
            return s;
        }
        let s = Arc::new(Solution::solve(scene, &self.layout, &self.params, seed));
        *self.solution.write().unwrap_or_else(|e| e.into_inner()) = Some(s.clone());
        s
    }

    /// A copy that renders with `solution` (the render driver's, for one render).
    pub fn with_solution(&self, solution: Arc<Solution>) -> Self {
        RadiosityIntegrator {
            fixed: Some(solution),
            ..self.clone()
        }
    }

    /// The solution kept from the last [`RadiosityIntegrator::prepare`].
    pub fn current(&self) -> Option<Arc<Solution>> {
        self.solution
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The radiance along a camera ray with the solution given to
    /// [`RadiosityIntegrator::with_solution`], else the one kept from the last
    /// [`RadiosityIntegrator::prepare`] (0 before any).
    #[inline]
    pub fn li_with_solution(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        match &self.fixed {
            Some(sol) => self.li(scene, sol, ray, sampler, stats),
            None => match self.current() {
                Some(sol) => self.li(scene, &sol, ray, sampler, stats),
                None => Spectrum::ZERO,
            },
        }
    }

    pub fn li(
        &self,
        scene: &Scene,
        sol: &Solution,
        ray: Ray,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        stats.rays += 1;
        let Some(si) = scene.intersect(&ray) else {
            return Spectrum::ZERO;
        };
        let radiance = |si: &SurfaceInteraction, d: Vec3, reflected_only: bool| {
            sol.patch_seen(&self.layout, si, d)
                .map_or(Spectrum::ZERO, |p| {
                    let p = p as usize;
                    let b = sol.radiosity[p]
                        - if reflected_only {
                            sol.patches[p].emission
                        } else {
                            Spectrum::ZERO
                        };
                    b / std::f32::consts::PI
                })
        };
        match self.params.shading {
            Shading::Flat => radiance(&si, ray.d, false),
            Shading::Gather => {
                stats.bounces += 1;
                let mut l = emission_at(scene, Some(&si), ray.d, NO_WAVELENGTHS);
                let bsdf = scene.shading_bsdf(&si, NO_WAVELENGTHS);
                let wi = si.frame.to_local(-ray.d.normalize());
                if let Some(e) = sample_emitter(
                    scene,
                    &si,
                    &bsdf,
                    wi,
                    sampler.next_2d(),
                    NO_WAVELENGTHS,
                    stats,
                ) {
                    l += e.value;
                }
                let (u1, u2) = (sampler.next_1d(), sampler.next_2d());
                if let Some(bs) = bsdf.sample(wi, u1, u2) {
                    let d = si.frame.to_world(bs.wo);
                    stats.rays += 1;
                    if let Some(hit) = scene.intersect(&Scene::spawn_ray(&si, d)) {
                        l += bs.weight * radiance(&hit, d, true);
                    }
                }
                l
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every (cell, side) draws its own stream: the estimates of different patches are
    /// independent, as the reciprocity test's variance (tests/radiosity.rs) assumes.
    #[test]
    fn each_patch_side_has_its_own_random_stream() {
        let mut firsts: Vec<[u32; 4]> = Vec::new();
        for cell in 0..256 {
            for side in 0..2u8 {
                let mut r = rng(7, cell, side);
                firsts.push(std::array::from_fn(|_| r.random::<u32>()));
            }
        }
        let n = firsts.len();
        firsts.sort_unstable();
        firsts.dedup();
        assert_eq!(
            firsts.len(),
            n,
            "two patch sides share their random numbers"
        );
    }
}
