//! Mitsuba's analytic `disk`: the unit disk in the local z = 0 plane, normal +z, placed by
//! `to_world`. Rays are intersected in local coordinates in f64, so the hit point lies on the
//! plane exactly before its final rounding to f32.

use super::{PositionSample, SurfaceInteraction};
use crate::geometry::{gamma, Frame, Ray};
use crate::sampling::square_to_uniform_disk_concentric;
use glam::{DMat4, DVec3, Vec2, Vec3};
use std::f64::consts::PI;

#[derive(Clone, Debug)]
pub struct Disk {
    to_world: DMat4,
    to_local: DMat4,
    normal: Vec3,
    area: f64,
}

impl Disk {
    /// `None` when `to_world` is singular (a disk without area).
    pub fn new(to_world: DMat4, flip_normals: bool) -> Option<Self> {
        let to_local = to_world.inverse();
        if !to_local.is_finite() || to_world.determinant() == 0.0 {
            return None;
        }
        let n = to_local
            .transpose()
            .transform_vector3(DVec3::Z)
            .try_normalize()?;
        let n = if flip_normals { -n } else { n };
        let axes = to_world
            .transform_vector3(DVec3::X)
            .cross(to_world.transform_vector3(DVec3::Y));
        Some(Disk {
            to_world,
            to_local,
            normal: n.as_vec3(),
            area: PI * axes.length(),
        })
    }

    pub fn area(&self) -> f64 {
        self.area
    }

    /// World-space bounds of the disk (the transformed square around it).
    pub fn corners(&self) -> [Vec3; 4] {
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(x, y)| {
            self.to_world
                .transform_point3(DVec3::new(x, y, 0.0))
                .as_vec3()
        })
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let o = self.to_local.transform_point3(ray.o.as_dvec3());
        let d = self.to_local.transform_vector3(ray.d.as_dvec3());
        if d.z == 0.0 {
            return None;
        }
        let t = -o.z / d.z;
        if t <= 0.0 || t >= ray.tmax as f64 {
            return None;
        }
        let x = o.x + t * d.x;
        let y = o.y + t * d.y;
        if x * x + y * y > 1.0 {
            return None;
        }
        let t32 = t as f32;
        (t32 > 0.0 && t32 < ray.tmax).then_some(t32)
    }

    fn world_point(&self, x: f64, y: f64) -> (Vec3, Vec3) {
        let p = self
            .to_world
            .transform_point3(DVec3::new(x, y, 0.0))
            .as_vec3();
        (p, p.abs() * gamma(3))
    }

    pub fn interaction(&self, ray: &Ray, t: f32, shape: u32) -> SurfaceInteraction {
        let o = self.to_local.transform_point3(ray.o.as_dvec3());
        let d = self.to_local.transform_vector3(ray.d.as_dvec3());
        let tl = -o.z / d.z;
        self.interaction_at(o.x + tl * d.x, o.y + tl * d.y, t, shape)
    }

    /// The point with surface coordinates `uv` (Mitsuba's `eval_parameterization`: radius u,
    /// angle 2π v).
    pub fn at_uv(&self, uv: Vec2, shape: u32) -> SurfaceInteraction {
        let (sin_phi, cos_phi) = crate::math::sin_cos(2.0 * PI * uv.y as f64);
        let r = uv.x as f64;
        self.interaction_at(r * cos_phi, r * sin_phi, 0.0, shape)
    }

    /// The interaction at local (x, y, 0).
    fn interaction_at(&self, x: f64, y: f64, t: f32, shape: u32) -> SurfaceInteraction {
        let (p, p_error) = self.world_point(x, y);
        let r = (x * x + y * y).sqrt();
        let phi = crate::math::atan2(y, x).rem_euclid(2.0 * PI);
        // Mitsuba's parameterisation: u = r, v = φ/2π; at the centre dp/du is zero and the
        // shading frame falls back to an arbitrary tangent, as in Mitsuba.
        let (cos_phi, sin_phi) = if r > 0.0 { (x / r, y / r) } else { (0.0, 0.0) };
        let dp_du = self
            .to_world
            .transform_vector3(DVec3::new(cos_phi, sin_phi, 0.0))
            .as_vec3();
        let dp_dv = self
            .to_world
            .transform_vector3(DVec3::new(-sin_phi, cos_phi, 0.0) * (2.0 * PI * r))
            .as_vec3();
        SurfaceInteraction {
            p,
            p_error,
            t,
            ng: self.normal,
            frame: Frame::from_normal_tangent(self.normal, dp_du),
            uv: Vec2::new(r as f32, (phi / (2.0 * PI)) as f32),
            dp_du,
            dp_dv,
            shape,
            prim: 0,
            bary: Vec2::ZERO,
        }
    }

    pub fn sample_position(&self, u: Vec2) -> PositionSample {
        let q = square_to_uniform_disk_concentric(u);
        let (p, p_error) = self.world_point(q.x as f64, q.y as f64);
        PositionSample {
            p,
            p_error,
            n: self.normal,
            pdf: (1.0 / self.area) as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transformed_disk_hits_misses_and_area() {
        let m = DMat4::from_translation(DVec3::new(0.0, 0.0, 5.0))
            * DMat4::from_scale(DVec3::new(2.0, 1.0, 1.0));
        let d = Disk::new(m, false).unwrap();
        assert!((d.area() - 2.0 * PI).abs() < 1e-12);
        let r = Ray::new(Vec3::new(1.9, 0.0, 0.0), Vec3::Z, f32::INFINITY);
        assert!((d.intersect(&r).unwrap() - 5.0).abs() < 1e-6);
        let r = Ray::new(Vec3::new(1.9, 0.5, 0.0), Vec3::Z, f32::INFINITY);
        assert!(d.intersect(&r).is_none(), "outside the ellipse");
        let r = Ray::new(Vec3::new(0.0, 0.0, 6.0), Vec3::Z, f32::INFINITY);
        assert!(d.intersect(&r).is_none(), "behind");
        let r = Ray::new(Vec3::new(0.0, 0.0, 6.0), -Vec3::Z, f32::INFINITY);
        let si = d.interaction(&r, d.intersect(&r).unwrap(), 0);
        assert!((si.ng - Vec3::Z).length() < 1e-6 && (si.p.z - 5.0).abs() < 1e-6);
        assert!(Disk::new(DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0)), false).is_none());
    }

    #[test]
    fn flipped_disk_normal_and_samples_on_plane() {
        let d = Disk::new(DMat4::from_rotation_x(0.5), true).unwrap();
        let n = DMat4::from_rotation_x(0.5)
            .transform_vector3(DVec3::Z)
            .as_vec3();
        assert!((d.normal + n).length() < 1e-6);
        for i in 0..50 {
            let s = d.sample_position(Vec2::new(i as f32 / 50.0, 0.3));
            assert!(s.p.dot(n).abs() < 1e-6);
            assert!(s.p.length() <= 1.0 + 1e-6);
        }
    }
}
