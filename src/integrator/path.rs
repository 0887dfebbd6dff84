//! Mitsuba's `path` integrator: unidirectional path tracing with next-event estimation at
//! every non-delta vertex, BSDF importance sampling, and both combined by multiple importance
//! sampling with the power heuristic (Veach and Guibas 1995; Veach 1997, ch. 9), plus Russian
//! roulette from `rr_depth` on.
//!
//! Depth semantics follow Mitsuba exactly: `max_depth` counts path segments, so 1 renders only
//! emitters seen directly and 2 adds direct lighting; Russian roulette applies once depth ≥
//! `rr_depth`, continuing with probability q = min(max(throughput) · η², 0.95).

use crate::bsdf::diffuse::DiffuseLanes;
use crate::geometry::{offset_ray_origin_lanes, Ray, Rays};
use crate::integrator::PathStats;
use crate::material::ShadingBsdf;
use crate::sampler::{Draws, SampleStream};
use crate::sampling::{mis_power, mis_power_lanes};
use crate::scene::Scene;
use crate::shape::{SurfaceInteraction, SurfaceInteractions};
use crate::simd::{for_each_lane, LaneF32, LaneMask, LaneU32, Lanes, Scalar, MAX_WIDTH, V3, V4};
use crate::spectrum::Spectrum;
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct PathIntegrator {
    /// Longest path, in segments; `u32::MAX` for unbounded.
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Directly visible emitters are not shown (camera rays pass through area lights).
    pub hide_emitters: bool,
}

// The per-vertex functions are `#[inline(always)]`: used by both engines, they are no
// longer inlined into `li` by LLVM's own choice, which cost the scalar engine 2.9% more
// instructions (callgrind, Cornell box 32x32, 8 spp).

/// One path between two bounces: what the loop of [`PathIntegrator::li`] carries from one
/// vertex to the next, the width-1 instance of the lane engine's paths ([`PathLanes`]).
/// Both engines call the same per-vertex functions below, so they compute the same numbers.
pub type PathState = PathLanes<Scalar>;

/// What a path does after the emission at a surface hit ([`PathIntegrator::at_surface`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SurfaceStep {
    /// The path ends here.
    End,
    /// Trace the state's ray again (a camera ray passing through a hidden emitter).
    Trace,
    /// Scatter at the hit ([`PathIntegrator::scatter`]), with the direction towards the
    /// previous vertex (world space, unit).
    Scatter { wi_world: Vec3 },
}

impl PathIntegrator {
    /// One path per camera ray: the loop of trace, [`PathIntegrator::at_surface`] (or
    /// [`PathIntegrator::escape`]) and [`PathIntegrator::scatter`].
    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        let Some(mut st) = self.start(ray, wl) else {
            return Spectrum::ZERO;
        };
        // Filled in place at vertices whose material varies (see `Scene::bsdf_at`).
        let mut bsdf_buf = ShadingBsdf::new();
        loop {
            stats.rays += 1;
            let Some(si) = scene.intersect(&st.ray.into()) else {
                self.escape(scene, &mut st);
                break;
            };
            match self.at_surface(scene, &mut st, si.shape, || si) {
                SurfaceStep::End => break,
                SurfaceStep::Trace => continue,
                SurfaceStep::Scatter { wi_world } => {
                    if !self.scatter(scene, &mut st, &si, wi_world, sampler, stats, &mut bsdf_buf) {
                        break;
                    }
                }
            }
        }
        st.result.into()
    }

    /// The state of a path whose camera ray is `ray`; `None` when `max_depth` is 0 (the path
    /// is black).
    #[inline(always)]
    pub fn start(&self, ray: Ray, wl: Vec4) -> Option<PathState> {
        if self.max_depth == 0 {
            return None;
        }
        Some(PathState {
            ray: ray.into(),
            throughput: Spectrum::ONE.into(),
            result: Spectrum::ZERO.into(),
            wl: [wl],
            eta: 1.0,
            depth: 0,
            prev_p: ray.o.into(),
            prev_bsdf_pdf: 1.0,
            prev_delta: true,
        })
    }

    /// The state's ray left the scene: the environment's emission, MIS-weighted against
    /// emitter sampling (camera rays and delta bounces: weight 1). With hide_emitters,
    /// camera rays that miss see black, as in Mitsuba. The path ends.
    #[inline(always)]
    pub fn escape(&self, scene: &Scene, st: &mut PathState) {
        if scene.environment.is_some() && !(st.depth == 0 && self.hide_emitters) {
            let d = Vec3::from(st.ray.d);
            let (le, pdf) = scene.environment_with_pdf(d, st.wl[0]);
            if le != Spectrum::ZERO {
                let w = if st.prev_delta {
                    1.0
                } else {
                    mis_power(st.prev_bsdf_pdf, pdf)
                };
                st.result = (Vec4::from(st.result) + Vec4::from(st.throughput) * le * w).into();
            }
        }
    }

    /// The state's ray hit shape `shape` at the interaction `si()`: its emission
    /// (MIS-weighted against emitter sampling), and whether the path goes on. `si` is
    /// called only where the shape emits (the lane engine then moves the interaction out
    /// of the lanes).
    #[inline(always)]
    pub fn at_surface(
        &self,
        scene: &Scene,
        st: &mut PathState,
        shape: u32,
        si: impl FnOnce() -> SurfaceInteraction,
    ) -> SurfaceStep {
        let d = Vec3::from(st.ray.d);
        let wi_world = -d.normalize();
        if let Some(e) = scene.shapes[shape as usize].emitter {
            let si = &si();
            if st.depth == 0 && self.hide_emitters {
                // Camera rays pass through directly visible emitters.
                st.ray = Scene::spawn_ray(si, d).into();
                return SurfaceStep::Trace;
            }
            let le = match &scene.emitters[e as usize] {
                crate::emitter::Emitter::Area(area) => {
                    area.eval(si, wi_world, &scene.shapes, st.wl[0])
                }
                _ => Spectrum::ZERO,
            };
            if le != Spectrum::ZERO {
                let w = if st.prev_delta {
                    1.0
                } else {
                    mis_power(
                        st.prev_bsdf_pdf,
                        scene.pdf_emitter_direction(st.prev_p.into(), si),
                    )
                };
                st.result = (Vec4::from(st.result) + Vec4::from(st.throughput) * le * w).into();
            }
        }
        if !self.goes_on_lanes(Scalar, st.depth) {
            return SurfaceStep::End;
        }
        SurfaceStep::Scatter { wi_world }
    }

    /// The vertex at `si`: next-event estimation, BSDF sampling of the next ray and Russian
    /// roulette; false when the path ends. `bsdf_buf` holds the BSDF where the material
    /// varies. The width-1 instance of [`PathIntegrator::scatter_lanes`].
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn scatter(
        &self,
        scene: &Scene,
        st: &mut PathState,
        si: &SurfaceInteraction,
        wi_world: Vec3,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
        bsdf_buf: &mut ShadingBsdf,
    ) -> bool {
        self.scatter_lanes(
            Scalar,
            scene,
            st,
            true,
            |_| *si,
            &SurfaceInteractions::from(si),
            wi_world.into(),
            &mut Draws::Streams(std::slice::from_mut(sampler)),
            stats,
            std::slice::from_mut(bsdf_buf),
        )
    }

    /// Whether paths whose last segment was their `depth`-th may scatter at the surface it
    /// reached: depth + 1 < max_depth (the scalar engine's [`PathIntegrator::at_surface`] and
    /// the lane engine's non-emitting hits share this rule).
    #[inline(always)]
    pub fn goes_on_lanes<L: Lanes>(&self, l: L, depth: L::U32) -> L::M {
        depth.cmp_lt(l.splat_u32(self.max_depth.saturating_sub(1)))
    }

    /// The vertices of the lanes of `m` (surface interactions `sis`, the directions towards
    /// the previous vertices `wi_world`): next-event estimation, BSDF sampling of the next
    /// rays and Russian roulette, each lane drawing from its own `samplers[i]` in the scalar
    /// order (emitter sample, BSDF sample, roulette). Where lane i's material varies over
    /// the surface, its BSDF is filled into `bufs[i]` from `si(i)`, lane i's interaction.
    /// Returns the lanes whose path goes on.
    ///
    /// Ported to lane kernels: emitter sampling (pick, point, solid-angle density), the
    /// shadow rays, the ray-origin offsets, MIS, the roulette's arithmetic, the directions'
    /// changes of frame (world to the shading frame and back), and the `diffuse` BSDF, alone
    /// or two-sided (eval, pdf, sample: [`DiffuseLanes`]), and the sample draws of the
    /// `independent` sampler ([`Draws::Independent`]; the other samplers draw lane by lane).
    /// Still lane by lane: the other BSDFs, the shadow rays' traversal.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn scatter_lanes<L: Lanes>(
        &self,
        l: L,
        scene: &Scene,
        st: &mut PathLanes<L>,
        m: L::M,
        si: impl Fn(usize) -> SurfaceInteraction,
        sis: &SurfaceInteractions<L>,
        wi_world: V3<L::F>,
        draws: &mut Draws<L>,
        stats: &mut PathStats,
        bufs: &mut [ShadingBsdf],
    ) -> L::M {
        let wi = sis.frame.to_local(wi_world);
        // Each lane draws in the scalar order: the emitter sample, the BSDF's (1D, 2D),
        // the roulette's.
        let (u0, u1) = draws.next_2d(l, m);
        let mut smooth = 0u32;
        let mut diffuse = DiffuseLanes::none(l);
        let (mut diffuse_bits, mut two_sided) = (0u32, 0u32);
        for_each_lane(
            L::WIDTH,
            m,
            #[inline(always)]
            |i| {
                stats.bounces += 1;
                let shape = sis.shape.lane(i);
                if scene.uniform_bsdf(shape).is_none() {
                    scene.shading_bsdf_into(&si(i), st.wl.as_ref()[i], &mut bufs[i]);
                }
                let bsdf = lane_bsdf(scene, shape, &bufs[i]);
                if let Some((front, back)) = bsdf.as_diffuse() {
                    // a smooth lobe for every wi
                    diffuse_bits |= 1 << i;
                    diffuse.front.set_lane(i, front);
                    if let Some(back) = back {
                        two_sided |= 1 << i;
                        diffuse.back.set_lane(i, back);
                    }
                    smooth |= 1 << i;
                } else if bsdf.has_smooth_lobe(wi.lane(i)) {
                    smooth |= 1 << i;
                }
            },
        );
        diffuse.m = l.mask(diffuse_bits);
        diffuse.two_sided = l.mask(two_sided);
        self.next_event_lanes(
            l,
            scene,
            st,
            l.mask(smooth),
            sis,
            wi,
            (u0, u1),
            stats,
            bufs,
            &diffuse,
        );
        let go = self.sample_bsdf_lanes(l, scene, st, m, sis, wi, draws, bufs, &diffuse);
        self.roulette_lanes(l, st, go, draws, stats)
    }

    /// Next-event estimation at the lanes of `m` (those whose BSDF has a smooth lobe): one
    /// emitter sample each (`u`), MIS-weighted against BSDF sampling, added to the result.
    /// The lanes of `diffuse` have a `diffuse` BSDF, evaluated in lanes; the others lane by
    /// lane.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn next_event_lanes<L: Lanes>(
        &self,
        l: L,
        scene: &Scene,
        st: &mut PathLanes<L>,
        m: L::M,
        sis: &SurfaceInteractions<L>,
        wi: V3<L::F>,
        u: (L::F, L::F),
        stats: &mut PathStats,
        bufs: &[ShadingBsdf],
        diffuse: &DiffuseLanes<L>,
    ) {
        if !m.any() {
            return;
        }
        let (sampled, ds) = scene.sample_emitter_direction_lanes(l, m, sis.p, u, st.wl.as_ref());
        let zero = l.splat(0.0);
        let wo = sis.frame.to_local(ds.d);
        let mut f = V4::splat(zero);
        let mut lit = 0u32;
        for_each_lane(
            L::WIDTH,
            sampled.and_not(diffuse.m),
            #[inline(always)]
            |i| {
                let bsdf = lane_bsdf(scene, sis.shape.lane(i), &bufs[i]);
                let f_i = bsdf.eval(wi.lane(i), wo.lane(i));
                if f_i != Spectrum::ZERO {
                    lit |= 1 << i;
                    f.set_lane(i, f_i);
                }
            },
        );
        let mut lit = l.mask(lit);
        let sampled_diffuse = sampled & diffuse.m;
        if sampled_diffuse.any() {
            let f_d = diffuse.eval(l, wi.z, wo.z);
            let lit_d = sampled_diffuse & !f_d.cmp_eq(V4::splat(zero));
            f = V4::select(lit_d, f_d, f);
            lit = lit | lit_d;
        }
        if !lit.any() {
            return;
        }
        let ray = Scene::shadow_ray_lanes(l, sis.p, sis.p_error, sis.ng, &ds);
        let delta = ds.delta.bits();
        let diffuse_bits = diffuse.m.bits();
        let mut bsdf_pdf = zero;
        stats.rays += lit.bits().count_ones() as u64;
        // The shadow rays of all lanes in one query (the scalar engine: its one ray).
        let occluded = if L::WIDTH == 1 {
            scene.occluded(&ray.lane(0)) as u32
        } else {
            let mut rays = [ray.lane(0); MAX_WIDTH];
            for_each_lane(L::WIDTH, lit, |i| rays[i] = ray.lane(i));
            scene.accel.occluded_lanes(&rays, lit.bits(), &scene.shapes)
        };
        let visible = lit.bits() & !occluded;
        for_each_lane(
            L::WIDTH,
            l.mask(visible),
            #[inline(always)]
            |i| {
                // Delta emitters cannot be found by BSDF sampling: no MIS, no BSDF density.
                if delta >> i & 1 == 0 && diffuse_bits >> i & 1 == 0 {
                    let bsdf = lane_bsdf(scene, sis.shape.lane(i), &bufs[i]);
                    bsdf_pdf.set_lane(i, bsdf.pdf(wi.lane(i), wo.lane(i)));
                }
            },
        );
        let visible = l.mask(visible);
        if !visible.any() {
            return;
        }
        if (visible & diffuse.m).any() {
            let pdf_d = diffuse.pdf(l, wi.z, wo.z);
            bsdf_pdf = L::F::select(diffuse.m, pdf_d, bsdf_pdf);
        }
        let value = f * ds.radiance / ds.pdf;
        let w = L::F::select(ds.delta, l.splat(1.0), mis_power_lanes(l, ds.pdf, bsdf_pdf));
        st.result = V4::select(visible, st.result + st.throughput * value * w, st.result);
    }

    /// BSDF sampling at the lanes of `m`: the next rays (from origins offset off the
    /// surfaces), throughputs and MIS state. Returns the lanes whose BSDF gave a direction.
    /// The lanes of `diffuse` (a `diffuse` BSDF) sample in lanes; the others lane by lane.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn sample_bsdf_lanes<L: Lanes>(
        &self,
        l: L,
        scene: &Scene,
        st: &mut PathLanes<L>,
        m: L::M,
        sis: &SurfaceInteractions<L>,
        wi: V3<L::F>,
        draws: &mut Draws<L>,
        bufs: &[ShadingBsdf],
        diffuse: &DiffuseLanes<L>,
    ) -> L::M {
        let zero = l.splat(0.0);
        let mut wo = V3::splat(zero);
        let mut weight = V4::splat(zero);
        let (mut pdf, mut eta) = (zero, zero);
        let (mut delta, mut go) = (0u32, 0u32);
        let u1 = draws.next_1d(l, m);
        let (u2x, u2y) = draws.next_2d(l, m);
        for_each_lane(
            L::WIDTH,
            m.and_not(diffuse.m),
            #[inline(always)]
            |i| {
                let bsdf = lane_bsdf(scene, sis.shape.lane(i), &bufs[i]);
                let u2 = glam::Vec2::new(u2x.lane(i), u2y.lane(i));
                if let Some(bs) = bsdf.sample(wi.lane(i), u1.lane(i), u2) {
                    go |= 1 << i;
                    wo.set_lane(i, bs.wo);
                    weight.set_lane(i, bs.weight);
                    pdf.set_lane(i, bs.pdf);
                    eta.set_lane(i, bs.eta);
                    delta |= (bs.delta as u32) << i;
                }
            },
        );
        let mut go = l.mask(go);
        if diffuse.m.any() {
            let d = diffuse.sample(l, wi.z, (u2x, u2y));
            let ok = d.ok;
            wo = V3::select(ok, d.wo, wo);
            weight = V4::select(ok, d.weight, weight);
            pdf = L::F::select(ok, d.pdf, pdf);
            eta = L::F::select(ok, l.splat(1.0), eta);
            go = go | ok;
        }
        if go.any() {
            let wo_world = sis.frame.to_world(wo);
            st.throughput = V4::select(go, st.throughput * weight, st.throughput);
            st.eta = L::F::select(go, st.eta * eta, st.eta);
            st.prev_p = V3::select(go, sis.p, st.prev_p);
            st.prev_bsdf_pdf = L::F::select(go, pdf, st.prev_bsdf_pdf);
            st.prev_delta = (go & l.mask(delta)) | st.prev_delta.and_not(go);
            let o = offset_ray_origin_lanes(l, sis.p, sis.p_error, sis.ng, wo_world);
            st.ray = Rays {
                o: V3::select(go, o, st.ray.o),
                d: V3::select(go, wo_world, st.ray.d),
                tmax: L::F::select(go, l.splat(f32::INFINITY), st.ray.tmax),
            };
            st.depth = L::U32::select(go, st.depth.wrapping_add(l.splat_u32(1)), st.depth);
        }
        go
    }

    /// Russian roulette after a bounce at the lanes of `m`: the lanes whose path goes on (a
    /// throughput left, and from `rr_depth` on kept with probability
    /// q = min(max(throughput) η², 0.95), their throughput divided by q).
    #[inline(always)]
    fn roulette_lanes<L: Lanes>(
        &self,
        l: L,
        st: &mut PathLanes<L>,
        m: L::M,
        draws: &mut Draws<L>,
        stats: &mut PathStats,
    ) -> L::M {
        let throughput_max = st.throughput.max_element();
        let alive = m & throughput_max.cmp_gt(l.splat(0.0)) & throughput_max.is_finite();
        let rr = alive.and_not(st.depth.cmp_lt(l.splat_u32(self.rr_depth)));
        if !rr.any() {
            return alive;
        }
        let q = (throughput_max * st.eta * st.eta).min(l.splat(0.95));
        let ended = rr & draws.next_1d(l, rr).cmp_ge(q);
        stats.rr_terminated += ended.bits().count_ones() as u64;
        st.throughput = V4::select(rr.and_not(ended), st.throughput / q, st.throughput);
        alive.and_not(ended)
    }
}

/// The BSDF of lane i at a hit on `shape`: the material's prebuilt one, else the lane's
/// buffer, filled at the vertex's first step ([`Scene::bsdf_at`]'s rule).
#[inline(always)]
fn lane_bsdf<'a>(scene: &'a Scene, shape: u32, buf: &'a ShadingBsdf) -> &'a ShadingBsdf {
    scene.uniform_bsdf(shape).unwrap_or(buf)
}

/// [`PathState`] in lanes: the paths of the lane engine (`integrator::lanes::path`), and at
/// width 1 the scalar engine's path in [`PathIntegrator::scatter`].
#[derive(Clone, Copy, Debug)]
pub struct PathLanes<L: Lanes> {
    pub ray: Rays<L>,
    pub throughput: V4<L::F>,
    pub result: V4<L::F>,
    /// Each lane's wavelengths (nm; spectral mode, else unused).
    pub wl: L::Wavelengths,
    pub eta: L::F,
    pub depth: L::U32,
    pub prev_p: V3<L::F>,
    pub prev_bsdf_pdf: L::F,
    pub prev_delta: L::M,
}

impl<L: Lanes> PathLanes<L> {
    #[inline(always)]
    pub fn zero(l: L) -> Self {
        let z = l.splat(0.0);
        let v = V3::splat(z);
        PathLanes {
            ray: Rays {
                o: v,
                d: v,
                tmax: z,
            },
            throughput: V4::splat(z),
            result: V4::splat(z),
            wl: L::Wavelengths::default(),
            eta: z,
            depth: l.splat_u32(0),
            prev_p: v,
            prev_bsdf_pdf: z,
            prev_delta: l.mask(0),
        }
    }

    /// Lane `i`'s path, out of the lanes.
    #[inline(always)]
    pub fn get(&self, i: usize) -> PathState {
        PathLanes {
            ray: self.ray.lane(i).into(),
            throughput: self.throughput.lane(i).into(),
            result: self.result.lane(i).into(),
            wl: [self.wl.as_ref()[i]],
            eta: self.eta.lane(i),
            depth: self.depth.lane(i),
            prev_p: self.prev_p.lane(i).into(),
            prev_bsdf_pdf: self.prev_bsdf_pdf.lane(i),
            prev_delta: self.prev_delta.bits() >> i & 1 != 0,
        }
    }

    /// Lane `i`'s path, back into the lanes.
    #[inline(always)]
    pub fn put(&mut self, l: L, i: usize, st: &PathState) {
        self.ray.o.set_lane(i, st.ray.o.into());
        self.ray.d.set_lane(i, st.ray.d.into());
        self.ray.tmax.set_lane(i, st.ray.tmax);
        self.throughput.set_lane(i, st.throughput.into());
        self.result.set_lane(i, st.result.into());
        self.wl.as_mut()[i] = st.wl[0];
        self.eta.set_lane(i, st.eta);
        self.depth.set_lane(i, st.depth);
        self.prev_p.set_lane(i, st.prev_p.into());
        self.prev_bsdf_pdf.set_lane(i, st.prev_bsdf_pdf);
        let bit = l.mask(1 << i);
        self.prev_delta = if st.prev_delta {
            self.prev_delta | bit
        } else {
            self.prev_delta.and_not(bit)
        };
    }
}
