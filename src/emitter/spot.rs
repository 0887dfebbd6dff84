//! Mitsuba's `spot` emitter: a point light at the origin of `to_world` shining down its local
//! +z axis with intensity I inside `beam_width`, falling off linearly in the angle from the
//! axis to 0 at `cutoff_angle` (Mitsuba 3.9.1's `falloff_curve`, measured: at cutoff 20°,
//! beam 15°, the intensity at 16° and 18° is 0.8 I and 0.4 I), optionally modulated by a
//! `texture` spread over the cone: the direction d (local frame) looks it up at
//! uv = ½ + ½ (d.x, d.y) / (d.z tan(cutoff_angle)).
//!
//! | parameter | default | |
//! |---|---|---|
//! | `intensity` | 1 | a colour (not spatially varying) |
//! | `texture` | none | a spatially varying texture (a bitmap) |
//! | `cutoff_angle` | 20° | |
//! | `beam_width` | ¾ cutoff_angle | |
//! | `to_world` | identity | the light looks down local +z |

use super::{DirectionSample, EmitterRay};
use crate::geometry::Ray;
use crate::sampling::square_to_uniform_cone;
use crate::texture::{ColorValue, Texture, TextureContext};
use glam::{DMat3, DMat4, DVec3, Mat3, Vec2, Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct SpotEmitter {
    pub position: Vec3,
    /// World to local directions: the inverse of `to_world`'s linear part (Mitsuba applies
    /// the whole inverse transform, so a scaled frame changes the cone as it does there).
    to_local: Mat3,
    /// Local to world directions (`to_world`'s linear part).
    to_world: Mat3,
    pub intensity: ColorValue,
    cutoff_angle: f32,
    cos_cutoff: f32,
    cos_beam: f32,
    inv_transition_width: f32,
    /// tan(cutoff_angle): the cone's edge at uv distance ½ from the centre.
    uv_factor: f32,
    beam_width: f32,
    texture: Option<Texture>,
}

impl SpotEmitter {
    /// A spot light with frame `to_world` (angles in degrees); `None` when the frame is
    /// degenerate.
    pub fn new(
        to_world: DMat4,
        intensity: ColorValue,
        cutoff_angle: f64,
        beam_width: f64,
        texture: Option<Texture>,
    ) -> Option<Self> {
        let linear = DMat3::from_mat4(to_world);
        if linear.determinant().abs() < 1e-300 || !linear.determinant().is_finite() {
            return None;
        }
        let (cutoff, beam) = (cutoff_angle.to_radians(), beam_width.to_radians());
        Some(SpotEmitter {
            position: to_world.transform_point3(DVec3::ZERO).as_vec3(),
            to_local: linear.inverse().as_mat3(),
            to_world: linear.as_mat3(),
            intensity,
            cutoff_angle: cutoff as f32,
            cos_cutoff: cutoff.cos() as f32,
            cos_beam: beam.cos() as f32,
            inv_transition_width: (1.0 / (cutoff - beam)) as f32,
            uv_factor: cutoff.tan() as f32,
            beam_width: beam as f32,
            texture,
        })
    }

    /// Mitsuba's falloff in local direction `d` (any length).
    pub fn falloff(&self, d: Vec3) -> f32 {
        let cos_theta = d.normalize_or_zero().z;
        if cos_theta <= self.cos_cutoff {
            0.0
        } else if cos_theta >= self.cos_beam {
            1.0
        } else {
            (self.cutoff_angle - crate::math::acosf(cos_theta.clamp(-1.0, 1.0)))
                * self.inv_transition_width
        }
    }

    /// The solid angle used for the power estimate: the cone halfway between beam and
    /// cutoff (exact for the linear falloff to first order).
    pub fn solid_angle(&self) -> f64 {
        let mid = 0.5 * (self.cutoff_angle as f64 + self.beam_width as f64);
        2.0 * std::f64::consts::PI * (1.0 - mid.cos())
    }

    /// The mean of the texture (1 without one).
    pub fn texture_mean(&self) -> f64 {
        self.texture.as_ref().map_or(1.0, |t| t.mean() as f64)
    }

    /// The texture's coordinates for local direction `d` (Mitsuba's `direction_to_uv`).
    fn direction_to_uv(&self, d: Vec3) -> Vec2 {
        Vec2::new(
            0.5 + 0.5 * d.x / (d.z * self.uv_factor),
            0.5 + 0.5 * d.y / (d.z * self.uv_factor),
        )
    }

    /// A ray in a direction drawn uniformly within the cutoff cone (as Mitsuba's
    /// `sample_ray`), weight I · falloff · texture / p_ω.
    pub fn sample_ray(&self, u: Vec2, wl: Vec4) -> Option<EmitterRay> {
        let local = square_to_uniform_cone(u, self.cos_cutoff);
        let pdf = 1.0 / (2.0 * std::f32::consts::PI * (1.0 - self.cos_cutoff));
        let mut weight = self.intensity.eval(wl) * (self.falloff(local) / pdf);
        if let Some(t) = &self.texture {
            weight *= t.eval(&TextureContext::at_uv_wl(self.direction_to_uv(local), wl));
        }
        let d = (self.to_world * local).normalize();
        Some(EmitterRay::from_point(
            Ray::new(self.position, d, f32::INFINITY),
            weight,
        ))
    }

    /// The solid-angle density with which [`SpotEmitter::sample_ray`] takes the world
    /// direction `d`: uniform within the cutoff cone.
    pub fn pdf_ray_direction(&self, d: Vec3) -> f32 {
        let local = (self.to_local * d).normalize_or_zero();
        if local.z >= self.cos_cutoff {
            1.0 / (2.0 * std::f32::consts::PI * (1.0 - self.cos_cutoff))
        } else {
            0.0
        }
    }

    pub fn sample_direction(&self, p_ref: Vec3, wl: Vec4) -> Option<DirectionSample> {
        let v = self.position - p_ref;
        let dist2 = v.length_squared();
        if !(dist2 > 0.0 && dist2.is_finite()) {
            return None;
        }
        let dist = dist2.sqrt();
        let d = v / dist;
        let local = self.to_local * -d;
        let f = self.falloff(local);
        if f <= 0.0 {
            return None;
        }
        let mut radiance = self.intensity.eval(wl) * (f / dist2);
        if let Some(t) = &self.texture {
            radiance *= t.eval(&TextureContext::at_uv_wl(self.direction_to_uv(local), wl));
        }
        Some(DirectionSample::from_point(
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

    /// Mitsuba's `direction_to_uv`: the texture spans the cutoff cone, uv = ½ + ½ (x, y) /
    /// (z tan θ_cutoff): the axis at the centre, the cone's edge at the texture's border.
    #[test]
    fn texture_coordinates_span_the_cutoff_cone() {
        let spot = SpotEmitter::new(
            DMat4::IDENTITY,
            ColorValue::Rgb(crate::spectrum::Spectrum::ONE),
            30.0,
            20.0,
            None,
        )
        .unwrap();
        let c = 30f32.to_radians();
        let at = |theta: f32, phi: f32| {
            let (s, z) = theta.sin_cos();
            spot.direction_to_uv(Vec3::new(s * phi.cos(), s * phi.sin(), z))
        };
        let close = |a: Vec2, b: Vec2| (a - b).abs().max_element() < 1e-5;
        assert!(close(at(0.0, 0.0), Vec2::splat(0.5)));
        assert!(close(at(c, 0.0), Vec2::new(1.0, 0.5)), "{}", at(c, 0.0));
        assert!(close(at(c, std::f32::consts::PI), Vec2::new(0.0, 0.5)));
        let half = 0.5 + 0.5 * (0.5 * c).tan() / c.tan();
        assert!(close(
            at(0.5 * c, std::f32::consts::FRAC_PI_2),
            Vec2::new(0.5, half)
        ));
    }
}
