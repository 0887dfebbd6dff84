//! Mitsuba's `projector` emitter: a pinhole at the origin of `to_world` projecting an image
//! along local +z, like a slide projector. With Mitsuba's normalisation, a white diffuse plane
//! facing it at distance 1 has radiance E = the `irradiance` texture's value (it receives
//! irradiance π E); the texture's aspect ratio (a bitmap's resolution, 1 for
//! a constant) and the field of view (`fov` along `fov_axis`, or `focal_length`, as a
//! perspective sensor's) fix the frustum.
//!
//! A point p seen from the projector in local coordinates (x, y, z), z > 0, receives the
//! texture at uv = (½ − ½ x / (z t), ½ − ½ a y / (z t)) with t = tan(fov_x / 2) and a the
//! aspect ratio (Mitsuba's `perspective_projection`, u growing towards −x), as the radiance
//! π · scale · E(uv) / (z² cos θ) from the projector's position, θ the angle between the
//! projection axis and the direction to p. Delta position: only next-event estimation finds
//! it.
//!
//! | parameter | default | |
//! |---|---|---|
//! | `irradiance` | 1 | texture (bitmap) or colour |
//! | `scale` | 1 | |
//! | `fov`, `fov_axis` / `focal_length` | 50mm | as Mitsuba's perspective sensor |
//! | `to_world` | identity | projects along local +z |

use super::{DirectionSample, EmitterRay};
use crate::geometry::Ray;
use crate::texture::{Texture, TextureContext};
use glam::{DMat4, DVec3, Mat4, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct ProjectorEmitter {
    position: Vec3,
    /// World to local (the inverse of `to_world`).
    to_local: Mat4,
    to_world: Mat4,
    /// `to_world` applied to the local +z axis (not normalised, as Mitsuba uses it).
    axis: Vec3,
    irradiance: Texture,
    scale: f32,
    /// 1 / tan(fov_x / 2).
    cot_half_fov: f32,
    aspect: f32,
}

impl ProjectorEmitter {
    /// `fov_x` in degrees, `aspect` = width / height of the irradiance texture; `None` for a
    /// degenerate frame.
    pub fn new(
        to_world: DMat4,
        irradiance: Texture,
        scale: f64,
        fov_x: f64,
        aspect: f64,
    ) -> Option<Self> {
        let det = to_world.determinant();
        if !(det.abs() > 1e-300 && det.is_finite()) {
            return None;
        }
        Some(ProjectorEmitter {
            position: to_world.transform_point3(DVec3::ZERO).as_vec3(),
            to_local: to_world.inverse().as_mat4(),
            to_world: to_world.as_mat4(),
            axis: to_world.transform_vector3(DVec3::Z).as_vec3(),
            irradiance,
            scale: scale as f32,
            cot_half_fov: (1.0 / (fov_x.to_radians() * 0.5).tan()) as f32,
            aspect: aspect as f32,
        })
    }

    /// The area of the image rectangle at distance 1 (for the power estimate).
    pub fn image_area(&self) -> f64 {
        let w = 2.0 / self.cot_half_fov as f64;
        w * w / self.aspect as f64
    }

    /// Mean irradiance over the image (for the power estimate).
    pub fn mean_irradiance(&self) -> f64 {
        self.irradiance.mean() as f64 * self.scale as f64
    }

    /// A ray through an image position drawn in proportion to the irradiance texture
    /// (density p_uv): the local direction (x, y, 1) with x = (1 − 2u) t, y = (1 − 2v) t / a
    /// spans the image rectangle of area A at distance 1, dω = A cos³θ du dv, and the
    /// intensity there is π · scale · E(uv) / cos³θ, so the weight is π · scale · E(uv) · A
    /// / p_uv (as Mitsuba's `sample_ray`).
    pub fn sample_ray(&self, u: Vec2, wl: glam::Vec4) -> Option<EmitterRay> {
        let (uv, pdf) = self.irradiance.sample_position(u);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let t = 1.0 / self.cot_half_fov;
        let local = Vec3::new(
            (1.0 - 2.0 * uv.x) * t,
            (1.0 - 2.0 * uv.y) * t / self.aspect,
            1.0,
        );
        let d = self.to_world.transform_vector3(local).normalize();
        let e = self.irradiance.eval(&TextureContext::at_uv_wl(uv, wl));
        let area = self.image_area() as f32;
        Some(EmitterRay::from_point(
            Ray::new(self.position, d, f32::INFINITY),
            e * (std::f32::consts::PI * self.scale * area / pdf),
        ))
    }

    /// The solid-angle density with which [`ProjectorEmitter::sample_ray`] takes the world
    /// direction `d`: p_uv / (A cos³θ) (see there), 0 outside the image.
    pub fn pdf_ray_direction(&self, d: Vec3) -> f32 {
        let local = self.to_local.transform_vector3(d);
        if local.z <= 0.0 {
            return 0.0;
        }
        let t = self.cot_half_fov / local.z;
        let uv = Vec2::new(
            0.5 - 0.5 * local.x * t,
            0.5 - 0.5 * self.aspect * local.y * t,
        );
        if !(uv.cmpge(Vec2::ZERO).all() && uv.cmple(Vec2::ONE).all()) {
            return 0.0;
        }
        let cos = local.z / local.length();
        let pdf = self.irradiance.pdf_position(uv) / (self.image_area() as f32 * cos * cos * cos);
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    pub fn sample_direction(&self, p_ref: Vec3, wl: glam::Vec4) -> Option<DirectionSample> {
        let local = self.to_local.transform_point3(p_ref);
        if local.z <= 0.0 {
            return None;
        }
        let t = self.cot_half_fov / local.z;
        let uv = Vec2::new(
            0.5 - 0.5 * local.x * t,
            0.5 - 0.5 * self.aspect * local.y * t,
        );
        if !(uv.cmpge(Vec2::ZERO).all() && uv.cmple(Vec2::ONE).all()) {
            return None;
        }
        let v = self.position - p_ref;
        let dist = v.length();
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        let d = v / dist;
        let cos = -self.axis.dot(d);
        let e = self.irradiance.eval(&TextureContext::at_uv_wl(uv, wl));
        let radiance = e * (std::f32::consts::PI * self.scale / (local.z * local.z * cos));
        radiance.is_finite().then_some(DirectionSample::from_point(
            self.position,
            d,
            dist,
            radiance,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A projector at height 1 over the plane z = 0 looking down, fov 90° (t = 1), square
    /// image: a white diffuse plane under it has radiance E (Mitsuba's normalisation), and
    /// the image covers |x|, |y| ≤ 1 exactly.
    #[test]
    fn a_white_plane_facing_it_shows_the_image() {
        // Mitsuba's <lookat origin="0, 0, 1" target="0, 0, 0" up="0, 1, 0"/>.
        let to_world = DMat4::from_cols(
            glam::DVec4::new(-1.0, 0.0, 0.0, 0.0),
            glam::DVec4::new(0.0, 1.0, 0.0, 0.0),
            glam::DVec4::new(0.0, 0.0, -1.0, 0.0),
            glam::DVec4::new(0.0, 0.0, 1.0, 1.0),
        );
        let e = crate::spectrum::rgb(2.0, 3.0, 4.0);
        let p = ProjectorEmitter::new(to_world, Texture::constant(e.truncate()), 1.0, 90.0, 1.0)
            .unwrap();
        let ds = p
            .sample_direction(Vec3::ZERO, crate::spectrum::NO_WAVELENGTHS)
            .unwrap();
        // Radiance of a white Lambertian plane: (1/π) cos θ · L.
        let radiance = ds.radiance * ds.d.z / std::f32::consts::PI;
        assert!((radiance - e).abs().max_element() < 1e-5, "{radiance}");
        assert!(p
            .sample_direction(Vec3::new(0.99, 0.0, 0.0), crate::spectrum::NO_WAVELENGTHS)
            .is_some());
        assert!(p
            .sample_direction(Vec3::new(1.01, 0.0, 0.0), crate::spectrum::NO_WAVELENGTHS)
            .is_none());
        assert!(p
            .sample_direction(Vec3::new(0.0, 0.0, 2.0), crate::spectrum::NO_WAVELENGTHS)
            .is_none());
    }
}
