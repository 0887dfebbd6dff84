//! Mitsuba's `ptracer` integrator: particle (light) tracing. Paths start on the emitters and
//! every surface vertex is connected to the camera's pinhole, adding its contribution to the
//! pixel it lands in (Arvo and Kirk 1990, "Particle transport and image synthesis"; Veach
//! 1997, §10.2 and §4.A; Mitsuba 3's `ptracer.cpp` for the semantics).
//!
//! One *particle* does what Mitsuba's `ParticleTracerIntegrator::sample` does:
//! 1. unless `hide_emitters` (or `max_depth` 0), a point on an emitter picked uniformly is
//!    connected to the camera: the emitters seen directly (area emitters by a point on their
//!    surface, environments by a direction from the camera; delta emitters cannot be seen);
//! 2. a ray leaves an emitter picked uniformly ([`Emitter::sample_ray`]); at every surface it
//!    meets, the vertex is connected to the camera through the BSDF in importance mode
//!    ([`ShadingBsdf::importance`]), then the path continues by BSDF sampling, with the
//!    shading-normal correction of the adjoint BSDF (Veach 1997, §5.3) and Russian roulette
//!    after `rr_depth` bounces (Mitsuba's `depth > rr_depth`, q = min(max(β) η², 0.95)).
//!
//! `max_depth` counts segments as for `path`: 1 shows only the emitters seen directly, 2
//! adds direct illumination, and so on. A render of `spp` samples per pixel traces
//! `spp · width · height` particles, each of weight 1/spp, so that the image is the same
//! estimate of the same pixel integral as a camera integrator's (Mitsuba's `sample_scale`).
//! Participating media are not supported, as in Mitsuba.
//!
//! [`Emitter::sample_ray`]: crate::emitter::Emitter::sample_ray
//! [`ShadingBsdf::importance`]: crate::material::ShadingBsdf::importance

use crate::geometry::{offset_ray_origin, Ray, SHADOW_EPSILON};
use crate::integrator::PathStats;
use crate::sampler::SampleStream;
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct ParticleTracer {
    /// Longest path, in segments; `u32::MAX` for unbounded.
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Emitters seen directly are not shown.
    pub hide_emitters: bool,
    /// Mitsuba's `samples_per_pass`: how many samples per pixel one pass traces (`None`: all
    /// of them in one pass). penumbra's renders already proceed in fixed-size batches, so
    /// it only has to divide the sample count, as Mitsuba requires.
    pub samples_per_pass: Option<u32>,
}

/// One contribution of a particle to the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Splat {
    /// Film position in [0,1]² (x right, y down).
    pub film: Vec2,
    pub value: Spectrum,
}

/// The shadow ray from `p` (error `p_error`, geometric normal `ng`, zero off surfaces) to the
/// pinhole at `target`, stopping a relative [`SHADOW_EPSILON`] short of it.
pub(crate) fn ray_to_camera(p: Vec3, p_error: Vec3, ng: Vec3, target: Vec3) -> Ray {
    let d0 = target - p;
    let from = offset_ray_origin(p, p_error, ng, d0);
    let v = target - from;
    let len = v.length();
    Ray::new(from, v / len, len * (1.0 - SHADOW_EPSILON))
}

/// Refuses what the light-path integrator `name` cannot render: participating media (as
/// Mitsuba's `ptracer`) and, for light tracing (`connects_to_camera`), a camera it cannot
/// connect to (a thin lens or an orthographic camera).
pub fn check_scene(
    name: &str,
    connects_to_camera: bool,
    camera: &crate::camera::Camera,
    has_media: bool,
) -> crate::error::Result<()> {
    use crate::error::Error;
    if connects_to_camera && !camera.supports_light_tracing() {
        return Err(Error::Invalid(format!(
            "the {name} integrator needs a pinhole perspective sensor (light paths cannot be \
             connected to a thinlens or orthographic one)"
        )));
    }
    if has_media {
        return Err(Error::Invalid(format!(
            "the {name} integrator does not support participating media: use volpath"
        )));
    }
    Ok(())
}

/// The adjoint BSDF's shading-normal correction (Veach 1997, §5.3) for light arriving from
/// `wi_world` and leaving towards `wo_world` (`wi`, `wo` the same in the shading frame) at a
/// surface of geometric normal `ng`: |cos_s(wi) (wo · ng) / (cos_s(wo) (wi · ng))|, or `None`
/// where a direction lies on different sides of the geometric and the shading normal (no
/// light leaks through shading normals).
pub(crate) fn adjoint_correction(
    ng: Vec3,
    wi_world: Vec3,
    wi: Vec3,
    wo_world: Vec3,
    wo: Vec3,
) -> Option<f32> {
    let (wi_ng, wo_ng) = (wi_world.dot(ng), wo_world.dot(ng));
    (wi_ng * wi.z > 0.0 && wo_ng * wo.z > 0.0).then(|| (wi.z * wo_ng / (wo.z * wi_ng)).abs())
}

/// What a light-path vertex at `si` sends to the camera point of `c` (light arriving with
/// throughput `throughput` from `wi_world`, `wi` in the shading frame; `bsdf` in importance
/// mode): throughput · f · (adjoint correction · W_e / dist²), the splat's value before the
/// visibility test ([`sees_camera`]); `None` where the directions lie on different sides of
/// the geometric and the shading normal.
pub(crate) fn camera_splat(
    si: &crate::shape::SurfaceInteraction,
    bsdf: &crate::material::ShadingBsdf,
    throughput: Spectrum,
    wi_world: Vec3,
    wi: Vec3,
    c: &crate::camera::SensorSample,
) -> Option<Spectrum> {
    let wo = si.frame.to_local(c.d);
    let correction = adjoint_correction(si.ng, wi_world, wi, c.d, wo)?;
    let f = bsdf.eval(wi, wo);
    Some(throughput * f * (correction * c.weight))
}

/// Whether nothing lies between the surface point `si` and the camera point `lens`.
pub(crate) fn sees_camera(
    scene: &Scene,
    si: &crate::shape::SurfaceInteraction,
    lens: Vec3,
) -> bool {
    !scene.occluded(&ray_to_camera(si.p, si.p_error, si.ng, lens))
}

impl ParticleTracer {
    /// Traces one particle at wavelengths `wl` (ignored in RGB mode), pushing its
    /// contributions (weight 1 each: the caller divides by the samples per pixel and, in
    /// spectral mode, converts them to RGB with the wavelengths' weights) to `splats`.
    pub fn trace(
        &self,
        scene: &Scene,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
        splats: &mut Vec<Splat>,
    ) {
        if scene.emitters.is_empty() || self.max_depth == 0 {
            return;
        }
        if !self.hide_emitters {
            self.sample_visible_emitter(scene, wl, sampler, stats, splats);
        }
        self.trace_light_path(scene, wl, sampler, stats, splats);
    }

    /// Picks an emitter as [`Scene::sample_emitter_direction`] does: its index and the
    /// inverse of its probability ([`ParticleTracer::trace`] has checked that the scene
    /// has emitters).
    fn pick_emitter(scene: &Scene, u: f32) -> (usize, f32) {
        scene
            .pick_emitter(u)
            .map_or((0, 0.0), |(i, _, pmf)| (i, 1.0 / pmf))
    }

    /// Step 1: an emitter seen directly by the camera.
    fn sample_visible_emitter(
        &self,
        scene: &Scene,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
        splats: &mut Vec<Splat>,
    ) {
        let (i, count) = Self::pick_emitter(scene, sampler.next_1d());
        let u = sampler.next_2d();
        let emitter = &scene.emitters[i];
        if emitter.is_delta() {
            return;
        }
        if emitter.is_environment() {
            return self.environment_from_camera(scene, wl, i, count, u, stats, splats);
        }
        let Some(pos) = emitter.sample_position(u, &scene.shapes, wl) else {
            return;
        };
        let Some(c) = scene.camera.sample_direction(pos.p) else {
            return;
        };
        let cos = pos.n.dot(c.d);
        if cos <= 0.0 {
            return; // the camera sees the emitter's back
        }
        let value = pos.radiance * (count * cos * c.weight / pos.pdf);
        if value.max_element() <= 0.0 {
            return;
        }
        stats.rays += 1;
        if scene.occluded(&ray_to_camera(pos.p, pos.p_error, pos.ng, c.p)) {
            return;
        }
        splats.push(Splat {
            film: c.film,
            value,
        });
    }

    /// An environment emitter seen from the camera: a direction drawn by the emitter from the
    /// pinhole, unoccluded to infinity. With W_e the camera's importance along it and p_ω
    /// the density, the contribution is L W_e / p_ω (the distance terms of Mitsuba's
    /// area-measure form cancel).
    #[allow(clippy::too_many_arguments)]
    fn environment_from_camera(
        &self,
        scene: &Scene,
        wl: Vec4,
        i: usize,
        count: f32,
        u: Vec2,
        stats: &mut PathStats,
        splats: &mut Vec<Splat>,
    ) {
        let origin = scene.camera.position();
        let Some(ds) = scene.emitters[i].sample_direction(origin, u, &scene.shapes, wl) else {
            return;
        };
        // A point at distance 1 along the direction carries W_e / 1².
        let Some(c) = scene.camera.sample_direction(origin + ds.d) else {
            return;
        };
        let value = ds.radiance * (count * c.weight / ds.pdf);
        if value.max_element().is_nan() || value.max_element() <= 0.0 {
            return;
        }
        stats.rays += 1;
        if scene.occluded(&Ray::new(origin, ds.d, f32::INFINITY)) {
            return;
        }
        splats.push(Splat {
            film: c.film,
            value,
        });
    }

    /// Step 2: a light path, each of its surface vertices connected to the camera.
    fn trace_light_path(
        &self,
        scene: &Scene,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
        splats: &mut Vec<Splat>,
    ) {
        let (i, count) = Self::pick_emitter(scene, sampler.next_1d());
        let u_dir = sampler.next_2d();
        let u_pos = sampler.next_2d();
        let Some(er) =
            scene.emitters[i].sample_ray(u_pos, u_dir, &scene.shapes, scene.bounding_sphere, wl)
        else {
            return;
        };
        let mut ray = er.ray;
        let mut throughput = er.weight * count;
        let mut eta = 1.0f32;
        let mut depth = 1u32;
        // Filled in place at each vertex (see `Scene::shading_bsdf_into`).
        let mut bsdf = crate::material::ShadingBsdf::new();
        while depth < self.max_depth {
            stats.rays += 1;
            let Some(si) = scene.intersect(&ray) else {
                break;
            };
            stats.bounces += 1;
            scene.shading_bsdf_into(&si, wl, &mut bsdf);
            bsdf.set_importance();
            // Towards where the light came from.
            let wi_world = -ray.d.normalize();
            let wi = si.frame.to_local(wi_world);

            // Connect the vertex to the camera.
            if let Some(c) = scene.camera.sample_direction(si.p) {
                if let Some(value) = camera_splat(&si, &bsdf, throughput, wi_world, wi, &c) {
                    if value.max_element() > 0.0 {
                        stats.rays += 1;
                        if sees_camera(scene, &si, c.p) {
                            splats.push(Splat {
                                film: c.film,
                                value,
                            });
                        }
                    }
                }
            }

            // Continue by sampling the BSDF.
            let u1 = sampler.next_1d();
            let u2 = sampler.next_2d();
            let Some(bs) = bsdf.sample(wi, u1, u2) else {
                break;
            };
            let wo_world = si.frame.to_world(bs.wo);
            let Some(correction) = adjoint_correction(si.ng, wi_world, wi, wo_world, bs.wo) else {
                break;
            };
            throughput *= bs.weight * correction;
            eta *= bs.eta;
            if !throughput.is_finite() || throughput.max_element() <= 0.0 {
                break;
            }
            depth += 1;
            if depth >= self.max_depth {
                break;
            }
            if depth > self.rr_depth {
                let q = (throughput.max_element() * eta * eta).min(0.95);
                if sampler.next_1d() >= q {
                    stats.rr_terminated += 1;
                    break;
                }
                throughput /= q;
            }
            ray = Scene::spawn_ray(&si, wo_world);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Bsdf, Diffuse};
    use crate::geometry::Frame;
    use crate::material::ShadingBsdf;

    /// The unit vector at `theta` degrees from +z, azimuth `phi` degrees from +x, computed in
    /// f64 (then rounded to f32).
    fn dir(theta: f64, phi: f64) -> Vec3 {
        let (t, p) = (theta.to_radians(), phi.to_radians());
        glam::DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()).as_vec3()
    }

    fn cos_deg(a: f64) -> f64 {
        a.to_radians().cos()
    }

    /// A surface of geometric normal +z whose shading normal leans 30° towards +x, and the
    /// correction for light arriving from `wi` (world) and leaving towards `wo` (world).
    fn tilted(wi: Vec3, wo: Vec3) -> Option<f32> {
        let frame = Frame::from_normal(dir(30.0, 0.0));
        adjoint_correction(Vec3::Z, wi, frame.to_local(wi), wo, frame.to_local(wo))
    }

    /// `got` within `rel` of `want`, relatively.
    fn assert_close(got: Option<f32>, want: f64, rel: f64, what: &str) {
        let got = got.unwrap_or_else(|| panic!("{what}: None, want {want}")) as f64;
        assert!(
            (got - want).abs() <= rel * want,
            "{what}: {got} vs {want} (relative {:.2e})",
            (got - want).abs() / want
        );
    }

    /// Veach 1997 (p. 155; Mitsuba's ptracer cites it) for light tracing with shading normals:
    /// light arriving from ω_i (towards the light) and leaving towards ω_o (towards the
    /// camera or the next vertex) carries |ω_i · n_s| |ω_o · n_g| / (|ω_i · n_g| |ω_o · n_s|)
    /// on top of the BSDF's value in importance mode, whose cosine is the shading one of ω_o.
    /// The expected values are written from the angles alone (θ from n_g = +z, the shading
    /// normal 30° towards +x, so in the xz plane the angle to n_s is θ ∓ 30°).
    #[test]
    fn adjoint_correction_follows_veach() {
        // Light 60° from n_g on the side n_s leans to (30° from n_s), leaving along n_g:
        // cos 30° · 1 / (cos 60° · cos 30°) = 2, exactly; the reverse is 1/2 (the factor is
        // not symmetric: exchanging ω_i and ω_o inverts it).
        assert_close(
            tilted(dir(60.0, 0.0), Vec3::Z),
            2.0,
            2e-6,
            "60° in, n_g out",
        );
        assert_close(
            tilted(Vec3::Z, dir(60.0, 0.0)),
            0.5,
            2e-6,
            "n_g in, 60° out",
        );
        // Along the shading normal both ways: 1.
        assert_close(
            tilted(dir(30.0, 0.0), dir(30.0, 0.0)),
            1.0,
            2e-6,
            "n_s both",
        );
        // Out of the plane of the tilt: ω_i 45° towards +y has ω_i · n_s = cos 45° cos 30°;
        // ω_o 20° towards −x is 50° from n_s: cos 45° cos 30° cos 20° / (cos 45° cos 50°).
        assert_close(
            tilted(dir(45.0, 90.0), dir(20.0, 180.0)),
            cos_deg(30.0) * cos_deg(20.0) / cos_deg(50.0),
            2e-6,
            "out of plane",
        );
        // Grazing the geometric surface, with the shading normal well away: light at 89.9°
        // (59.9° from n_s) is multiplied by ~332, light leaving at 89.9° by ~1/332 of that.
        let graze = cos_deg(59.9) / (cos_deg(89.9) * cos_deg(30.0));
        assert!(graze > 300.0, "{graze}");
        assert_close(tilted(dir(89.9, 0.0), Vec3::Z), graze, 1e-5, "grazing in");
        assert_close(
            tilted(Vec3::Z, dir(89.9, 0.0)),
            cos_deg(30.0) * cos_deg(89.9) / cos_deg(59.9),
            1e-5,
            "grazing out",
        );
        // Grazing the shading surface: light 59.9° towards −x is 89.9° from n_s. Its
        // ω_i · n_s = 0.0017 is a difference of f32 products of 0.43, each rounded by ~3e-8:
        // a relative error of up to ~1e-4.
        assert_close(
            tilted(dir(59.9, 180.0), Vec3::Z),
            cos_deg(89.9) / (cos_deg(59.9) * cos_deg(30.0)),
            5e-4,
            "grazing n_s in",
        );
        // Both directions below both normals (transmission on the same side of both):
        // ω_o at 150° is 120° from n_s: cos 30° |cos 150°| / (1 · |cos 120°|) = 3/2.
        assert_close(tilted(Vec3::Z, dir(150.0, 0.0)), 1.5, 2e-6, "transmitted");
        // A direction between the two horizons leaks no light: None, on either side.
        for (wi, wo, what) in [
            (dir(70.0, 180.0), Vec3::Z, "in above n_g, below n_s"),
            (Vec3::Z, dir(70.0, 180.0), "out above n_g, below n_s"),
            (dir(100.0, 0.0), Vec3::Z, "in below n_g, above n_s"),
            (Vec3::Z, dir(100.0, 0.0), "out below n_g, above n_s"),
        ] {
            assert_eq!(tilted(wi, wo), None, "{what}");
        }
    }

    /// Where the shading normal is the geometric one the correction is 1 for any pair of
    /// directions on one side, and the factors of (ω_i, ω_o) and (ω_o, ω_i) multiply to 1
    /// for any normals.
    #[test]
    fn adjoint_correction_is_one_without_shading_normals() {
        let flat = Frame::from_normal(Vec3::Z);
        let tilt = Frame::from_normal(dir(40.0, 120.0));
        for i in 0..64 {
            let (a, b) = (i as f64 * 1.37, i as f64 * 5.3);
            let wi = dir(85.0 * ((a * 0.61).sin() * 0.5 + 0.5), b * 47.0);
            let wo = dir(85.0 * ((b * 0.37).cos() * 0.5 + 0.5), a * 71.0);
            let c = adjoint_correction(Vec3::Z, wi, flat.to_local(wi), wo, flat.to_local(wo));
            assert!(
                (c.expect("both above") - 1.0).abs() < 1e-6,
                "{wi} {wo}: {c:?}"
            );
            let (li, lo) = (tilt.to_local(wi), tilt.to_local(wo));
            if let Some(f) = adjoint_correction(Vec3::Z, wi, li, wo, lo) {
                let r = adjoint_correction(Vec3::Z, wo, lo, wi, li).expect("the same sides");
                assert!((f * r - 1.0).abs() < 1e-4, "{wi} {wo}: {f} · {r}");
            }
        }
    }

    /// What the correction is for: the light tracer's value at a vertex, the BSDF in
    /// importance mode times the correction per unit geometric cosine towards the camera,
    /// equals the path tracer's, the BSDF in radiance mode with the directions exchanged per
    /// unit geometric cosine towards the light (the pixel's flux is the same integral over
    /// the same area measure both ways). Without the correction the two differ by the
    /// factor itself.
    #[test]
    fn corrected_importance_matches_radiance_per_geometric_cosine() {
        let mut bsdf = ShadingBsdf::leaf(Bsdf::Diffuse(Diffuse {
            reflectance: crate::spectrum::rgb(0.7, 0.5, 0.3),
        }));
        let radiance = bsdf.clone();
        bsdf.set_importance();
        let frame = Frame::from_normal(dir(35.0, 20.0));
        let ng = Vec3::Z;
        for (wl, wc) in [
            (dir(60.0, 0.0), dir(10.0, 200.0)),
            (dir(20.0, 90.0), dir(70.0, 30.0)),
            (dir(85.0, 10.0), dir(5.0, 0.0)),
        ] {
            let (l, c) = (frame.to_local(wl), frame.to_local(wc));
            let k = adjoint_correction(ng, wl, l, wc, c).expect("both above both normals");
            let light = bsdf.eval(l, c) * k / wc.dot(ng);
            let path = radiance.eval(c, l) / wl.dot(ng);
            assert!(
                (light - path).abs().max_element() <= 1e-5 * path.max_element(),
                "{wl} → {wc}: {light} vs {path}"
            );
            assert!(
                (k - 1.0).abs() > 0.05,
                "{wl} → {wc}: factor {k} too close to 1"
            );
        }
    }
}
