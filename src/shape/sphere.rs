//! Mitsuba's analytic `sphere`: ray intersection solved in f64 with the numerically stable
//! quadratic of Hearn and Baker as discussed in Haines et al., "Precision Improvements for
//! Ray/Sphere Intersection" (Ray Tracing Gems ch. 7), and the hit point re-projected onto the
//! sphere, so its error is just the final rounding to f32.

use super::{PositionSample, SurfaceInteraction};
use crate::geometry::{gamma, Frame, Ray};
use crate::sampling::square_to_uniform_sphere;
use glam::{DMat3, DVec3, Vec2, Vec3};
use std::f64::consts::PI;

/// A sphere placed by a similarity transform: `center`, `radius`, and the rotation of its
/// local frame, which decides its (u, v) = (φ/2π, θ/π) parameterisation as in Mitsuba
/// (local +z is the pole, φ measured from local +x).
#[derive(Clone, Debug)]
pub struct Sphere {
    pub center: DVec3,
    pub radius: f64,
    pub flip_normals: bool,
    /// Columns: the local x, y, z axes in world space (orthonormal).
    pub rotation: DMat3,
}

impl Sphere {
    /// A sphere whose local axes are the world axes.
    pub fn new(center: DVec3, radius: f64, flip_normals: bool) -> Self {
        Sphere {
            center,
            radius,
            flip_normals,
            rotation: DMat3::IDENTITY,
        }
    }

    pub fn area(&self) -> f64 {
        4.0 * PI * self.radius * self.radius
    }

    /// Smallest root of |o + t d − c| = r with 0 < t < ray.tmax.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let o = ray.o.as_dvec3();
        let d = ray.d.as_dvec3();
        let f = o - self.center;
        let a = d.length_squared();
        let b = -f.dot(d);
        let l = f + (b / a) * d; // from the centre to the closest point of the line
        let r2 = self.radius * self.radius;
        let disc = a * (r2 - l.length_squared());
        if disc < 0.0 || a == 0.0 {
            return None;
        }
        let c = f.length_squared() - r2;
        let q = b + disc.sqrt().copysign(b);
        let (mut t0, mut t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q / a) };
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        let tmax = ray.tmax as f64;
        let t = if t0 > 0.0 { t0 } else { t1 };
        if t <= 0.0 || t >= tmax {
            return None;
        }
        let t32 = t as f32;
        (t32 > 0.0 && t32 < ray.tmax).then_some(t32)
    }

    fn normal_at(&self, p: DVec3) -> Vec3 {
        let n = ((p - self.center) / self.radius)
            .normalize_or_zero()
            .as_vec3();
        if self.flip_normals {
            -n
        } else {
            n
        }
    }

    fn rounded(p: DVec3) -> (Vec3, Vec3) {
        let p32 = p.as_vec3();
        (p32, p32.abs() * gamma(3))
    }

    pub fn interaction(&self, ray: &Ray, t: f32, shape: u32) -> SurfaceInteraction {
        let hit = ray.o.as_dvec3() + ray.d.as_dvec3() * t as f64;
        let local = hit - self.center;
        self.interaction_at(local * (self.radius / local.length()), t, shape)
    }

    /// The point with surface coordinates `uv` (Mitsuba's `eval_parameterization`:
    /// φ = 2π u, θ = π v in the sphere's frame).
    pub fn at_uv(&self, uv: Vec2, shape: u32) -> SurfaceInteraction {
        let (sin_phi, cos_phi) = crate::math::sin_cos(2.0 * PI * uv.x as f64);
        let (sin_theta, cos_theta) = crate::math::sin_cos(PI * uv.y as f64);
        let q = DVec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta);
        self.interaction_at(self.rotation * q * self.radius, 0.0, shape)
    }

    /// The interaction at `local` = the point minus the centre (length `radius`).
    fn interaction_at(&self, local: DVec3, t: f32, shape: u32) -> SurfaceInteraction {
        let (p, p_error) = Self::rounded(self.center + local);
        let n = self.normal_at(self.center + local);
        // Mitsuba's parameterisation, in the sphere's own frame (unit radius).
        let q = self.rotation.transpose() * local / self.radius;
        let phi = crate::math::atan2(q.y, q.x).rem_euclid(2.0 * PI);
        let theta = crate::math::acos(q.z.clamp(-1.0, 1.0));
        let rd = (q.x * q.x + q.y * q.y).sqrt();
        let dp_du = DVec3::new(-q.y, q.x, 0.0) * (2.0 * PI);
        let dp_dv = if rd > 0.0 {
            DVec3::new(q.z * q.x / rd, q.z * q.y / rd, -rd) * PI
        } else {
            DVec3::new(PI, 0.0, 0.0)
        };
        let to_world = self.rotation * self.radius;
        let dp_du = (to_world * dp_du).as_vec3();
        SurfaceInteraction {
            p,
            p_error,
            t,
            ng: n,
            frame: Frame::from_normal_tangent(n, dp_du),
            uv: Vec2::new((phi / (2.0 * PI)) as f32, (theta / PI) as f32),
            dp_du,
            dp_dv: (to_world * dp_dv).as_vec3(),
            shape,
            prim: 0,
            bary: Vec2::ZERO,
        }
    }

    pub fn sample_position(&self, u: Vec2) -> PositionSample {
        let w = square_to_uniform_sphere(u).as_dvec3();
        self.position_at(w)
    }

    /// The point of the sphere in direction `w` (any length) from the centre, with its
    /// normal, error bound and the uniform area density.
    pub fn position_at(&self, w: DVec3) -> PositionSample {
        let p = self.center + w.normalize() * self.radius;
        let (p32, p_error) = Self::rounded(p);
        PositionSample {
            p: p32,
            p_error,
            n: self.normal_at(p),
            pdf: (1.0 / self.area()) as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Sphere {
        Sphere::new(DVec3::new(1.0, 2.0, 3.0), 2.0, false)
    }

    #[test]
    fn hits_from_outside_and_inside() {
        let s = unit();
        let r = Ray::new(Vec3::new(1.0, 2.0, 10.0), -Vec3::Z, f32::INFINITY);
        let t = s.intersect(&r).unwrap();
        assert!((t - 5.0).abs() < 1e-6);
        let si = s.interaction(&r, t, 0);
        assert!((si.ng - Vec3::Z).length() < 1e-6);
        // from the centre: the far side
        let r = Ray::new(Vec3::new(1.0, 2.0, 3.0), Vec3::X, f32::INFINITY);
        assert!((s.intersect(&r).unwrap() - 2.0).abs() < 1e-6);
    }

    #[test]
    fn misses_and_respects_tmax() {
        let s = unit();
        assert!(s
            .intersect(&Ray::new(
                Vec3::new(4.0, 2.0, 10.0),
                -Vec3::Z,
                f32::INFINITY
            ))
            .is_none());
        assert!(s
            .intersect(&Ray::new(Vec3::new(1.0, 2.0, 10.0), Vec3::Z, f32::INFINITY))
            .is_none());
        assert!(s
            .intersect(&Ray::new(Vec3::new(1.0, 2.0, 10.0), -Vec3::Z, 4.9))
            .is_none());
    }

    #[test]
    fn grazing_ray_hits_near_the_silhouette() {
        let s = unit();
        let r = Ray::new(Vec3::new(2.999, 2.0, 10.0), -Vec3::Z, f32::INFINITY);
        let t = s.intersect(&r).unwrap();
        let si = s.interaction(&r, t, 0);
        assert!((si.p.as_dvec3() - s.center).length() - 2.0 < 1e-6);
    }

    #[test]
    fn far_from_origin_hit_point_is_on_the_surface() {
        let s = Sphere::new(DVec3::new(1e5, -1e5, 1e5), 1e-2, true);
        let o = Vec3::new(1e5, -1e5, 1e5 + 1.0);
        let r = Ray::new(o, -Vec3::Z, f32::INFINITY);
        let t = s.intersect(&r).unwrap();
        let si = s.interaction(&r, t, 0);
        assert!((si.p.z as f64 - (1e5 + 1e-2)).abs() <= si.p_error.z as f64 + 1e-9);
        assert!(si.ng.z < -0.99, "flipped normal points inward");
    }

    #[test]
    fn sampled_points_lie_on_the_sphere() {
        let s = unit();
        for i in 0..100 {
            let u = Vec2::new(i as f32 / 100.0, (i * 37 % 100) as f32 / 100.0);
            let ps = s.sample_position(u);
            let r = (ps.p.as_dvec3() - s.center).length();
            assert!((r - 2.0).abs() < 1e-5);
            assert!((ps.pdf as f64 - 1.0 / s.area()).abs() < 1e-9);
        }
    }
}
