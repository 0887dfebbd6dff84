//! The lane engine of Mitsuba's `path` integrator ([`PathIntegrator`]): one tile's camera
//! samples traced in the lanes of a backend, each iteration one bounce of every active lane:
//!
//! 1. refill: every free lane takes the next (pixel, sample) pair of the tile's queue, in
//!    the scalar engine's order (pixel by pixel, samples ascending), and its camera ray;
//! 2. intersect every active lane's ray, and compute the surface interactions at the hits:
//!    on meshes outside instances by the lane kernel ([`triangle_interactions`], once for
//!    every mesh hit, each lane's triangle loaded from its own mesh), elsewhere lane by
//!    lane;
//! 3. at each hit, the emission and whether the path goes on: in lanes where the shape
//!    does not emit (the direction back to the previous vertex, the end at max_depth),
//!    lane by lane ([`PathIntegrator::escape`], [`PathIntegrator::at_surface`]) where the
//!    ray left the scene under an environment or hit an emitter;
//! 4. at the lanes that go on, next-event estimation, BSDF sampling and Russian roulette
//!    ([`PathIntegrator::scatter_lanes`], whose lane kernels run on all of them at once);
//!
//! and a lane whose path ended writes its result into the tile's slot for its sample.
//! The path state lives in lanes ([`PathLanes`]); the traversal of step 2 and the emission
//! of step 3 are the scalar code called lane by lane on the state moved out of and back into
//! the lanes.

use super::LaneStats;
use crate::accel::Hit;
use crate::geometry::Ray;
use crate::integrator::path::{PathIntegrator, PathLanes, SurfaceStep};
use crate::integrator::PathStats;
use crate::material::ShadingBsdf;
use crate::sampler::pcg::PcgLanes;
use crate::sampler::{Draws, SampleStream};
use crate::scene::Scene;
use crate::shape::{triangle_interactions, ShapeGeometry, SurfaceInteractions, TriangleLanes};
use crate::simd::MAX_WIDTH;
use crate::simd::{
    dispatch, lanes_of, Backend, LaneF32, LaneMask, LaneProgram, LaneU32, Lanes, V3,
};
use crate::spectrum::Spectrum;
use glam::Vec2;

/// One camera sample: its sample stream (past the camera's dimensions), its film position
/// in pixels, and its ray.
pub type CameraSample = (SampleStream, Vec2, Ray);

/// What one tile asks of the lane engine: `total` camera samples, sample q made by
/// `camera(q)` (q in the scalar engine's order), their values written to `out[q]`. In
/// spectral mode (the scene's) each sample draws its four wavelengths from its stream right
/// after the camera's dimensions, as the scalar engine does, and writes them with their
/// weights to `wavelengths[q]`; the caller converts the values.
pub struct TileQueue<'a> {
    pub scene: &'a Scene,
    pub path: &'a PathIntegrator,
    pub total: usize,
    pub camera: &'a (dyn Fn(usize) -> CameraSample + Sync),
}

/// A spectral sample's wavelengths and their weights (1 / pdf).
pub type SampledWavelengths = (glam::Vec4, glam::Vec4);

/// Traces `queue` in lanes of `backend`, writing each sample's film position and value to
/// `out` (at least `queue.total` long) and adding to the counters. False (and nothing
/// traced) if this processor does not run the backend.
pub fn trace_tile(
    backend: Backend,
    queue: &TileQueue,
    out: &mut [(Vec2, Spectrum)],
    wavelengths: &mut [SampledWavelengths],
    stats: &mut PathStats,
    lanes: &mut LaneStats,
) -> bool {
    assert!(out.len() >= queue.total, "one result slot per sample");
    assert!(
        queue.scene.mode == crate::spectrum::Mode::Rgb || wavelengths.len() >= queue.total,
        "one wavelength slot per sample in spectral mode"
    );
    dispatch(
        backend,
        TileProgram {
            queue,
            out,
            wavelengths,
            stats,
            lanes,
        },
    )
    .is_some()
}

struct TileProgram<'a, 'b> {
    queue: &'a TileQueue<'b>,
    out: &'a mut [(Vec2, Spectrum)],
    wavelengths: &'a mut [SampledWavelengths],
    stats: &'a mut PathStats,
    lanes: &'a mut LaneStats,
}

impl LaneProgram for TileProgram<'_, '_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        trace_queue(
            l,
            self.queue,
            self.out,
            self.wavelengths,
            self.stats,
            self.lanes,
        )
    }
}

/// The paths in the lanes ([`PathLanes`]), plus what the lane engine keeps per lane (its
/// sample's slot and film position, its sample stream, the direction to the previous vertex
/// between the emission and scatter steps).
struct Paths<L: Lanes> {
    l: L,
    active: L::M,
    st: PathLanes<L>,
    wi_world: V3<L::F>,
    /// The sample's index in the tile's queue.
    slot: L::U32,
    film_x: L::F,
    film_y: L::F,
    samplers: [SampleStream; MAX_WIDTH],
    /// The lanes' generators, where the render's sampler is `independent`: its draws are
    /// made for all lanes at once from these ([`Draws::Independent`]), not from `samplers`.
    pcg: PcgLanes<L>,
}

impl<L: Lanes> Paths<L> {
    #[inline(always)]
    fn new(l: L) -> Self {
        let zero = l.splat(0.0);
        Paths {
            l,
            active: l.mask(0),
            st: PathLanes::zero(l),
            wi_world: V3::splat(zero),
            slot: l.splat_u32(0),
            film_x: zero,
            film_y: zero,
            samplers: std::array::from_fn(|_| SampleStream::new(0, 0, 0)),
            pcg: PcgLanes::zero(l),
        }
    }

    /// Lane `i`'s path has ended with `result`: its sample's slot gets it, the lane is free.
    #[inline(always)]
    fn finish(&mut self, i: usize, result: Spectrum, out: &mut [(Vec2, Spectrum)]) {
        let pos = Vec2::new(self.film_x.lane(i), self.film_y.lane(i));
        out[self.slot.lane(i) as usize] = (pos, result);
        self.active = self.active.and_not(self.l.mask(1 << i));
    }
}

#[inline(always)]
fn trace_queue<L: Lanes>(
    l: L,
    queue: &TileQueue,
    out: &mut [(Vec2, Spectrum)],
    wavelengths: &mut [SampledWavelengths],
    stats: &mut PathStats,
    counters: &mut LaneStats,
) {
    let spectral = queue.scene.mode == crate::spectrum::Mode::Spectral;
    let TileQueue {
        scene,
        path,
        total,
        camera,
    } = *queue;
    let width = L::WIDTH;
    let all = l.mask(u32::MAX);
    let mut p = Paths::new(l);
    // What each lane's ray hit, and where, between the intersection and the later steps.
    let mut hits: [Option<Hit>; MAX_WIDTH] = [None; MAX_WIDTH];
    let mut rays = [Ray::new(glam::Vec3::ZERO, glam::Vec3::Z, 0.0); MAX_WIDTH];
    let mut sis = SurfaceInteractions::zero(l);
    // Where the lanes' materials vary, their BSDFs, filled in place (see `Scene::bsdf_at`).
    let mut bsdf_bufs = vec![ShadingBsdf::new(); width];
    let mut next = 0usize;
    // Every sample of a render has the same sampler: whether it is `independent` is read
    // off the first one.
    let mut independent = None;
    counters.width = width as u64;
    loop {
        // 1. Refill the free lanes, lowest first, from the queue.
        let mut free = (all.and_not(p.active)).bits();
        while free != 0 && next < total {
            let i = free.trailing_zeros() as usize;
            let q = next;
            next += 1;
            let (mut sampler, pos, ray) = camera(q);
            let wl = if spectral {
                wavelengths[q] = crate::spectral::sample_wavelengths(sampler.next_1d());
                wavelengths[q].0
            } else {
                crate::spectrum::NO_WAVELENGTHS
            };
            let Some(st) = path.start(ray, wl) else {
                // (max_depth 0: the path is black and takes no lane)
                out[q] = (pos, Spectrum::ZERO);
                continue;
            };
            p.st.put(l, i, &st);
            let pcg = sampler.independent_pcg();
            let independent = *independent.get_or_insert(pcg.is_some());
            debug_assert_eq!(independent, pcg.is_some(), "one sampler per render");
            if let (true, Some(g)) = (independent, pcg) {
                p.pcg.set_lane(i, &g);
            }
            p.samplers[i] = sampler;
            p.slot.set_lane(i, q as u32);
            p.film_x.set_lane(i, pos.x);
            p.film_y.set_lane(i, pos.y);
            p.active = p.active | l.mask(1 << i);
            free &= free - 1;
        }
        if !p.active.any() {
            break;
        }
        let active = p.active.bits();
        let n = active.count_ones();
        counters.iterations += 1;
        counters.traced += n as u64;
        counters.by_active[n as usize] += 1;
        for i in lanes_of(active) {
            let d = (p.st.depth.lane(i) as usize).min(LaneStats::DEPTHS - 1);
            counters.by_depth[d] += 1;
        }

        // 2. Intersect, and the interactions at the hits: on meshes outside instances by
        // the lane kernel, once for all of them (each lane's triangle loaded from its own
        // mesh); elsewhere (analytic shapes, instances) lane by lane.
        let zero = l.splat(0.0);
        let mut tl = TriangleLanes::zero(l);
        let (mut t, mut b1, mut b2) = (zero, zero, zero);
        let mut on_mesh = 0u32;
        for i in lanes_of(active) {
            rays[i] = p.st.ray.lane(i);
        }
        stats.rays += n as u64;
        scene
            .accel
            .intersect_lanes(&rays, active, &scene.shapes, &mut hits);
        for i in lanes_of(active) {
            let ray = rays[i];
            let Some(hit) = &hits[i] else {
                continue;
            };
            if let Some((s, k)) = scene.accel.mesh_triangle(hit) {
                if let ShapeGeometry::Mesh(mesh) = &scene.shapes[s as usize].geometry {
                    mesh.load_triangle(&mut tl, i, k, s);
                    on_mesh |= 1 << i;
                    t.set_lane(i, hit.t);
                    b1.set_lane(i, hit.b1);
                    b2.set_lane(i, hit.b2);
                    continue;
                }
            }
            sis.set_lane(i, &scene.accel.interaction(hit, &ray, &scene.shapes));
        }
        if on_mesh != 0 {
            let r = triangle_interactions(l, &tl, t, b1, b2);
            sis = SurfaceInteractions::select(l.mask(on_mesh), &r, &sis);
        }

        // 3. Emission where the rays ended; which paths go on. Lanes whose ray left the
        // scene or hit an emitter run the scalar steps (`escape`, `at_surface`) on their
        // state moved out of the lanes; the others (a hit on a shape that does not emit: no
        // emission, the path ends only at max_depth) stay in the lanes, with
        // `at_surface`'s arithmetic in lanes: wi = -d / |d|, and its end at max_depth
        // ([`PathIntegrator::goes_on_lanes`]).
        let mut hit_bits = 0u32;
        let mut emits = 0u32;
        for i in lanes_of(active) {
            if hits[i].is_some() {
                hit_bits |= 1 << i;
                let shape = sis.shape.lane(i) as usize;
                emits |= (scene.shapes[shape].emitter.is_some() as u32) << i;
            } else if scene.environment.is_some() {
                let mut st = p.st.get(i);
                path.escape(scene, &mut st);
                p.finish(i, st.result.into(), out);
            } else {
                p.finish(i, p.st.result.lane(i), out);
            }
        }
        let mut scatter = 0u32;
        for i in lanes_of(emits) {
            let mut st = p.st.get(i);
            match path.at_surface(scene, &mut st, sis.shape.lane(i), || sis.lane(i)) {
                SurfaceStep::End => p.finish(i, st.result.into(), out),
                SurfaceStep::Trace => p.st.put(l, i, &st),
                SurfaceStep::Scatter { wi_world } => {
                    p.st.put(l, i, &st);
                    p.wi_world.set_lane(i, wi_world);
                    scatter |= 1 << i;
                }
            }
        }
        let plain = l.mask(hit_bits & !emits);
        if plain.any() {
            let more = path.goes_on_lanes(l, p.st.depth);
            let goes_on = plain & more;
            p.wi_world = V3::select(goes_on, -p.st.ray.d.normalize(l.splat(1.0)), p.wi_world);
            scatter |= goes_on.bits();
            for i in lanes_of(plain.and_not(more).bits()) {
                p.finish(i, p.st.result.lane(i), out);
            }
        }
        counters.scattered += scatter.count_ones() as u64;
        if scatter == 0 {
            continue;
        }

        // 4. Next-event estimation, BSDF sampling, Russian roulette.
        let scatter = l.mask(scatter);
        let go = path.scatter_lanes(
            l,
            scene,
            &mut p.st,
            scatter,
            #[inline(always)]
            |i| sis.lane(i),
            &sis,
            p.wi_world,
            &mut if independent == Some(true) {
                Draws::Independent(&mut p.pcg)
            } else {
                Draws::Streams(&mut p.samplers)
            },
            stats,
            &mut bsdf_bufs,
        );
        for i in lanes_of(scatter.and_not(go).bits()) {
            p.finish(i, p.st.result.lane(i), out);
        }
    }
}
