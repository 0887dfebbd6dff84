//! Mitsuba's `perspective` sensor: a pinhole camera looking down its local +z axis, with
//! local +y up and local +x to the *left* of the image (Mitsuba's convention, so that
//! `lookat` cameras are not mirrored). Film position (0,0) is the top-left corner.
//!
//! Mitsuba's `thinlens` sensor is the same camera with a thin lens (Kolb, Mitchell and
//! Hanrahan 1995; pbrt-v4 §5.2.3): rays start at a point sampled uniformly on the aperture
//! disk of radius `aperture_radius` (concentric map) in the local z = 0 plane and pass
//! through the point that the pinhole ray meets on the plane of focus z = `focus_distance`,
//! which is therefore imaged sharply.

use crate::geometry::Ray;
use crate::sampling::square_to_uniform_disk_concentric;
use glam::{DMat4, DVec3, Vec2, Vec3};

/// Which image axis `fov` spans (Mitsuba's `fov_axis`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FovAxis {
    X,
    Y,
    Diagonal,
    Smaller,
    Larger,
}

/// Converts a field of view (degrees) along `axis` into the horizontal field of view, as
/// Mitsuba does for an image of aspect ratio `aspect` = width / height.
pub fn fov_x_degrees(fov: f64, axis: FovAxis, aspect: f64) -> f64 {
    let to_x = |tan_half: f64| 2.0 * tan_half.atan().to_degrees();
    let tan_half = (fov.to_radians() * 0.5).tan();
    match axis {
        FovAxis::X => fov,
        FovAxis::Y => to_x(tan_half * aspect),
        FovAxis::Diagonal => to_x(tan_half * aspect / (aspect * aspect + 1.0).sqrt()),
        FovAxis::Smaller => {
            if aspect > 1.0 {
                to_x(tan_half * aspect)
            } else {
                fov
            }
        }
        FovAxis::Larger => {
            if aspect > 1.0 {
                fov
            } else {
                to_x(tan_half * aspect)
            }
        }
    }
}

#[derive(Clone, Debug)]
pub struct PerspectiveCamera {
    origin: Vec3,
    /// Camera-to-world linear part (columns: left, up, forward).
    x: Vec3,
    y: Vec3,
    z: Vec3,
    tan_half_x: f64,
    aspect: f64,
    near_clip: f32,
    far_clip: f32,
    /// The thin lens, if any (`None`: pinhole).
    lens: Option<ThinLens>,
}

/// Aperture and focus of a `thinlens` sensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinLens {
    pub aperture_radius: f64,
    pub focus_distance: f64,
}

impl PerspectiveCamera {
    /// `fov_x` in degrees, in (0, 180); `aspect` = width / height.
    pub fn new(to_world: DMat4, fov_x: f64, aspect: f64, near_clip: f64, far_clip: f64) -> Self {
        let col = |i: usize| to_world.col(i).truncate();
        PerspectiveCamera {
            origin: to_world.transform_point3(DVec3::ZERO).as_vec3(),
            x: col(0).as_vec3(),
            y: col(1).as_vec3(),
            z: col(2).as_vec3(),
            tan_half_x: (fov_x.to_radians() * 0.5).tan(),
            aspect,
            near_clip: near_clip as f32,
            far_clip: far_clip as f32,
            lens: None,
        }
    }

    /// The same camera with a thin lens (Mitsuba's `thinlens`).
    pub fn with_thin_lens(mut self, lens: ThinLens) -> Self {
        self.lens = Some(lens);
        self
    }

    /// Whether rays need an aperture sample (Mitsuba's `needs_aperture_sample`): the sampler
    /// then draws it right after the pixel position.
    pub fn needs_aperture_sample(&self) -> bool {
        self.lens.is_some()
    }

    /// The primary ray through film position `s` ∈ [0,1]² and, for a thin lens, the aperture
    /// sample `u` ∈ [0,1)² (ignored by a pinhole). Starts on the near clipping plane and ends
    /// on the far one (measured along the local z axis), as in Mitsuba.
    pub fn generate_ray_lens(&self, s: Vec2, u: Vec2) -> Ray {
        let Some(lens) = self.lens else {
            return self.generate_ray(s);
        };
        let x = (1.0 - 2.0 * s.x as f64) * self.tan_half_x;
        let y = (1.0 - 2.0 * s.y as f64) * self.tan_half_x / self.aspect;
        // The pinhole ray meets the plane of focus at (x, y, 1) · focus_distance.
        let focus = DVec3::new(x, y, 1.0) * lens.focus_distance;
        let a = square_to_uniform_disk_concentric(u).as_dvec2() * lens.aperture_radius;
        let o_local = DVec3::new(a.x, a.y, 0.0);
        let d_local = (focus - o_local).normalize();
        let inv_z = 1.0 / d_local.z;
        let near_t = self.near_clip as f64 * inv_z;
        let far_t = self.far_clip as f64 * inv_z;
        let (xa, ya, za) = (self.x.as_dvec3(), self.y.as_dvec3(), self.z.as_dvec3());
        let o = self.origin.as_dvec3() + xa * o_local.x + ya * o_local.y;
        let d = (xa * d_local.x + ya * d_local.y + za * d_local.z).normalize();
        Ray::new(
            (o + d * near_t).as_vec3(),
            d.as_vec3(),
            (far_t - near_t) as f32,
        )
    }

    /// The local (camera-space) unit direction through film position `s` ∈ [0,1]².
    pub fn local_direction(&self, s: Vec2) -> Vec3 {
        let x = (1.0 - 2.0 * s.x as f64) * self.tan_half_x;
        let y = (1.0 - 2.0 * s.y as f64) * self.tan_half_x / self.aspect;
        DVec3::new(x, y, 1.0).normalize().as_vec3()
    }

    /// The primary ray through film position `s` ∈ [0,1]² (x right, y down). It starts on
    /// the near clipping plane and ends on the far one, as in Mitsuba.
    pub fn generate_ray(&self, s: Vec2) -> Ray {
        let local = self.local_direction(s);
        let inv_z = 1.0 / local.z;
        let near_t = self.near_clip * inv_z;
        let far_t = self.far_clip * inv_z;
        let d = (self.x * local.x + self.y * local.y + self.z * local.z).normalize();
        Ray::new(self.origin + d * near_t, d, far_t - near_t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn look(origin: DVec3, target: DVec3, up: DVec3) -> DMat4 {
        let dir = (target - origin).normalize();
        let left = up.cross(dir).normalize();
        let new_up = dir.cross(left);
        DMat4::from_cols(
            left.extend(0.0),
            new_up.extend(0.0),
            dir.extend(0.0),
            origin.extend(1.0),
        )
    }

    #[test]
    fn corners_and_centre_for_each_fov_axis() {
        // 200x100 image (aspect 2), camera at the origin looking down -z with +y up.
        let m = look(DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0), DVec3::Y);
        let aspect = 2.0;
        let centre_dir = |fov_x| {
            PerspectiveCamera::new(m, fov_x, aspect, 1e-2, 1e4)
                .generate_ray(Vec2::splat(0.5))
                .d
        };
        assert!((centre_dir(90.0) - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        for (axis, fov, tan_x, tan_y) in [
            (FovAxis::X, 90.0, 1.0, 0.5),
            (FovAxis::Y, 90.0, 2.0, 1.0),
            (FovAxis::Smaller, 90.0, 2.0, 1.0),
            (FovAxis::Larger, 90.0, 1.0, 0.5),
            (
                FovAxis::Diagonal,
                90.0,
                2.0 / 5f64.sqrt(),
                1.0 / 5f64.sqrt(),
            ),
        ] {
            let cam =
                PerspectiveCamera::new(m, fov_x_degrees(fov, axis, aspect), aspect, 1e-2, 1e4);
            // top-left corner of the image: left (-x world, since the camera looks down -z
            // with left = +x local = up × dir = -x world... ) and up.
            let r = cam.generate_ray(Vec2::ZERO);
            let d = r.d / -r.d.z;
            assert!((d.x as f64 + tan_x).abs() < 1e-5, "{axis:?}: {d}");
            assert!((d.y as f64 - tan_y).abs() < 1e-5, "{axis:?}: {d}");
            let r = cam.generate_ray(Vec2::ONE);
            let d = r.d / -r.d.z;
            assert!((d.x as f64 - tan_x).abs() < 1e-5 && (d.y as f64 + tan_y).abs() < 1e-5);
        }
    }

    #[test]
    fn ray_starts_on_near_plane_and_ends_on_far_plane() {
        let m = look(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y);
        let cam = PerspectiveCamera::new(m, 60.0, 1.0, 0.5, 100.0);
        let r = cam.generate_ray(Vec2::new(0.1, 0.8));
        let start_depth = (5.0 - r.o.z) as f64;
        let end_depth = (5.0 - r.at(r.tmax).z) as f64;
        assert!((start_depth - 0.5).abs() < 1e-5 && (end_depth - 100.0).abs() < 1e-3);
    }
}
