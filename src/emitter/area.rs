//! Mitsuba's `area` emitter: radiance leaving one side of a shape, the side its (shading)
//! normal points to.
//!
//! A constant radiance is sampled by choosing a point uniformly by area on the shape and
//! converting the area density to solid angle, p_ω = p_A r² / |cos θ_light| (Veach 1997, eq.
//! 8.10) — except on spheres seen from outside, which are sampled uniformly within the cone
//! of directions they subtend, p_ω = 1 / (2π (1 − cos θmax)) with sin θmax = r / |c − p|
//! (Shirley, Wang and Zimmerman 1996, "Monte Carlo techniques for direct lighting
//! calculations"; pbrt-v4 §6.2.4), as Mitsuba does.
//!
//! A textured radiance (a bitmap) is sampled as Mitsuba does: a texture coordinate drawn in
//! proportion to the texels ([`Texture::sample_position`]), mapped onto the shape
//! ([`ShapeGeometry::at_uv`]), p_A = p_uv / |∂p/∂u × ∂p/∂v|, with the geometric normal for the
//! solid-angle conversion.

use super::{DirectionSample, DirectionSamples, EmitterPosition, EmitterRay};
use crate::geometry::{offset_ray_origin, Frame, Ray};
use crate::sampling::{square_to_cosine_hemisphere, square_to_uniform_cone};
use crate::shape::{
    Mesh, PositionSamples, Shape, ShapeGeometry, Sphere, SurfaceInteraction, UvGrid,
};
use crate::simd::{LaneF32, Lanes, Scalar, V3, V4};
use crate::spectrum::{from_rgb, Spectrum};
use crate::texture::{Texture, TextureContext};
use glam::{DVec3, Vec2, Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct AreaEmitter {
    /// Index of the shape this emitter is attached to.
    pub shape: u32,
    pub radiance: Texture,
    /// For a textured radiance on a mesh: where each uv lies on it.
    pub uv_grid: Option<UvGrid>,
}

/// The cone a sphere subtends from `p_ref`: (unit axis towards the centre, distance to the
/// centre, cos θmax, 1 − cos θmax), or `None` when `p_ref` is inside or on the sphere. Points
/// within a relative 5e-5 of the surface count as on it (area sampling, valid on both sides):
/// a path vertex on the sphere itself lies on either side by rounding, and from just outside
/// the cone's near intersection would be the vertex itself.
fn sphere_cone(s: &Sphere, p_ref: Vec3) -> Option<(DVec3, f64, f64, f64)> {
    let v = s.center - p_ref.as_dvec3();
    let dc2 = v.length_squared();
    let r2 = s.radius * s.radius;
    if dc2 <= r2 * (1.0 + 1e-4) {
        return None;
    }
    let dc = dc2.sqrt();
    let sin2 = r2 / dc2;
    let cos_max = (1.0 - sin2).max(0.0).sqrt();
    // 1 − cos θmax without cancellation for small spheres.
    let one_minus = sin2 / (1.0 + cos_max);
    Some((v / dc, dc, cos_max, one_minus))
}

/// The radiance texture's lookup context at `si` on `geometry`.
fn texture_context<'a>(
    si: &SurfaceInteraction,
    geometry: &'a ShapeGeometry,
    wl: Vec4,
) -> TextureContext<'a> {
    TextureContext {
        uv: si.uv,
        p: si.p,
        prim: si.prim,
        bary: si.bary,
        mesh: match geometry {
            ShapeGeometry::Mesh(m) => Some(m),
            _ => None,
        },
        wavelengths: wl,
    }
}

/// A point uniform by area on `mesh`, seen from `p_ref`, lane by lane where `m` is set.
#[inline(always)]
fn by_area_lanes<L: Lanes>(
    l: L,
    m: L::M,
    mesh: &Mesh,
    p_ref: V3<L::F>,
    u: (L::F, L::F),
    radiance: V4<L::F>,
) -> (L::M, DirectionSamples<L>) {
    let (ok, ps) = mesh.sample_position_lanes(l, m, u.0, u.1);
    to_solid_angle_lanes(l, ok, &ps, p_ref, radiance)
}

/// Points sampled by area (`ps`, where `m` is set) as directions from `p_ref`, lane by lane:
/// the unit direction, the distance, and the area density converted to solid angle,
/// p_A r² / cos θ_light (Veach 1997, eq. 8.10). A lane fails where the point coincides with
/// `p_ref` or the distance overflows, where it sees the emitter's back side (which emits
/// nothing), or where the density is not finite and positive.
#[inline(always)]
fn to_solid_angle_lanes<L: Lanes>(
    l: L,
    m: L::M,
    ps: &PositionSamples<L>,
    p_ref: V3<L::F>,
    radiance: V4<L::F>,
) -> (L::M, DirectionSamples<L>) {
    let zero = l.splat(0.0);
    let v = ps.p - p_ref;
    let dist2 = v.length_squared();
    let dist = dist2.sqrt();
    let d = v / dist;
    let cos_light = ps.n.dot(-d);
    let pdf = ps.pdf * dist2 / cos_light;
    let ok = m
        & dist2.cmp_ne(zero)
        & dist2.is_finite()
        & cos_light.cmp_gt(zero)
        & pdf.is_finite()
        & pdf.cmp_gt(zero);
    (
        ok,
        DirectionSamples {
            p: ps.p,
            p_error: ps.p_error,
            n: ps.n,
            d,
            dist,
            pdf,
            radiance,
            delta: l.mask(0),
        },
    )
}

impl AreaEmitter {
    /// An area emitter on shape `shape` (of `shapes`): a textured radiance on a mesh needs
    /// its texture coordinates (`None` without them).
    pub fn new(shape: u32, radiance: Texture, shapes: &[Shape]) -> Option<Self> {
        let uv_grid = match (
            &shapes.get(shape as usize)?.geometry,
            radiance.is_spatially_varying(),
        ) {
            (ShapeGeometry::Mesh(m), true) => Some(UvGrid::new(m)?),
            (ShapeGeometry::SdfGrid(_), true) => return None,
            _ => None,
        };
        Some(AreaEmitter {
            shape,
            radiance,
            uv_grid,
        })
    }

    /// Radiance leaving the surface at `si` in direction `w` (world, pointing away from the
    /// surface).
    #[inline]
    pub fn eval(&self, si: &SurfaceInteraction, w: Vec3, shapes: &[Shape], wl: Vec4) -> Spectrum {
        if si.frame.n.dot(w) <= 0.0 {
            return Spectrum::ZERO;
        }
        match &self.radiance {
            Texture::Constant { rgb, .. } => from_rgb(*rgb),
            Texture::Spectral { value, .. } => value.eval(wl),
            t => t.eval(&texture_context(
                si,
                &shapes[self.shape as usize].geometry,
                wl,
            )),
        }
    }

    /// The mean radiance (for power estimates).
    pub fn mean_radiance(&self) -> f64 {
        match &self.radiance {
            Texture::Constant { rgb, .. } => (rgb.x as f64 + rgb.y as f64 + rgb.z as f64) / 3.0,
            t => t.mean() as f64,
        }
    }

    pub fn sample_direction(
        &self,
        p_ref: Vec3,
        u: Vec2,
        shapes: &[Shape],
        wl: Vec4,
    ) -> Option<DirectionSample> {
        let geometry = &shapes[self.shape as usize].geometry;
        let radiance = match &self.radiance {
            Texture::Constant { rgb, .. } => from_rgb(*rgb),
            Texture::Spectral { value, .. } => {
                // Spectral mode: the constant's geometry with unit radiance, then the spectrum.
                let mut ds = self.sample_constant(Spectrum::ONE, p_ref, u, geometry)?;
                ds.radiance *= value.eval(wl);
                return Some(ds);
            }
            _ => return self.sample_textured(p_ref, u, geometry, wl),
        };
        self.sample_constant(radiance, p_ref, u, geometry)
    }

    /// [`AreaEmitter::sample_direction`] for a radiance that does not vary over the surface.
    fn sample_constant(
        &self,
        radiance: Spectrum,
        p_ref: Vec3,
        u: Vec2,
        geometry: &ShapeGeometry,
    ) -> Option<DirectionSample> {
        if let ShapeGeometry::Sphere(s) = geometry {
            if let Some(cone) = sphere_cone(s, p_ref) {
                return self.sample_sphere_cone(radiance, s, p_ref, u, cone);
            }
        }
        // Uniform by area, converted to solid angle: the width-1 instance of the lane
        // kernel (meshes), or of its conversion (the analytic shapes).
        let (ok, ds) = match geometry {
            ShapeGeometry::Mesh(mesh) => by_area_lanes(
                Scalar,
                true,
                mesh,
                p_ref.into(),
                (u.x, u.y),
                radiance.into(),
            ),
            _ => {
                let ps = geometry.sample_position(u)?;
                let mut pss = PositionSamples::zero(Scalar);
                pss.set_lane(0, &ps);
                to_solid_angle_lanes(Scalar, true, &pss, p_ref.into(), radiance.into())
            }
        };
        ok.then(|| ds.lane(0))
    }

    /// [`AreaEmitter::sample_direction`] lane by lane where `m` is set, for a constant
    /// radiance on a mesh (the Cornell family's area lights): a point uniform by area
    /// ([`Mesh::sample_position_lanes`]) converted to solid angle. `None` for every other
    /// emitter (the caller runs the scalar code lane by lane): spheres sample the cone they
    /// subtend in f64 with sin and cos, and textured radiance searches the texture.
    #[inline(always)]
    pub fn sample_direction_lanes<L: Lanes>(
        &self,
        l: L,
        m: L::M,
        p_ref: V3<L::F>,
        u: (L::F, L::F),
        shapes: &[Shape],
    ) -> Option<(L::M, DirectionSamples<L>)> {
        match (&self.radiance, &shapes[self.shape as usize].geometry) {
            (Texture::Constant { rgb, .. }, ShapeGeometry::Mesh(mesh)) => {
                let radiance = V4::new(
                    l.splat(rgb.x),
                    l.splat(rgb.y),
                    l.splat(rgb.z),
                    l.splat(rgb.y),
                );
                Some(by_area_lanes(l, m, mesh, p_ref, u, radiance))
            }
            _ => None,
        }
    }

    /// Mitsuba's strategy for a spatially varying radiance: uv by the texture, mapped onto
    /// the shape.
    fn sample_textured(
        &self,
        p_ref: Vec3,
        u: Vec2,
        geometry: &ShapeGeometry,
        wl: Vec4,
    ) -> Option<DirectionSample> {
        let (uv, pdf_uv) = self.radiance.sample_position(u);
        if pdf_uv.is_nan() || pdf_uv <= 0.0 {
            return None;
        }
        let si = geometry.at_uv(uv, self.uv_grid.as_ref(), self.shape)?;
        let jacobian = si.dp_du.cross(si.dp_dv).length();
        let v = si.p - p_ref;
        let dist2 = v.length_squared();
        let dist = dist2.sqrt();
        let d = v / dist;
        let cos_light = -si.ng.dot(d);
        if !(cos_light > 0.0 && jacobian > 0.0 && dist > 0.0) {
            return None;
        }
        let pdf = pdf_uv / jacobian * dist2 / cos_light;
        let radiance = self.radiance.eval(&texture_context(&si, geometry, wl));
        (pdf.is_finite() && pdf > 0.0).then_some(DirectionSample {
            p: si.p,
            p_error: si.p_error,
            n: si.ng,
            d,
            dist,
            pdf,
            radiance,
            delta: false,
        })
    }

    fn sample_sphere_cone(
        &self,
        radiance: Spectrum,
        s: &Sphere,
        p_ref: Vec3,
        u: Vec2,
        (axis, dc, cos_max, one_minus): (DVec3, f64, f64, f64),
    ) -> Option<DirectionSample> {
        let local = square_to_uniform_cone(u, cos_max as f32).as_dvec3();
        let frame = Frame::from_normal(axis.as_vec3());
        let d = (frame.s.as_dvec3() * local.x
            + frame.t.as_dvec3() * local.y
            + frame.n.as_dvec3() * local.z)
            .normalize();
        // First intersection of the ray p_ref + t d with the sphere (the near side), in f64;
        // directions at the rim graze it (the discriminant is clamped to 0 there).
        let cos_t = d.dot(axis);
        let disc = (s.radius * s.radius - dc * dc * (1.0 - cos_t * cos_t)).max(0.0);
        let t = (dc * cos_t - disc.sqrt()).max(0.0);
        let hit = p_ref.as_dvec3() + d * t;
        let ps = s.position_at(hit - s.center);
        let v = ps.p - p_ref;
        let dist = v.length();
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        let d = v / dist;
        let radiance = if ps.n.dot(-d) > 0.0 {
            radiance
        } else {
            Spectrum::ZERO // a sphere emitting inwards, seen from outside
        };
        let pdf = (1.0 / (2.0 * std::f64::consts::PI * one_minus)) as f32;
        (pdf.is_finite() && pdf > 0.0).then_some(DirectionSample {
            p: ps.p,
            p_error: ps.p_error,
            n: ps.n,
            d,
            dist,
            pdf,
            radiance,
            delta: false,
        })
    }

    /// A point on the emitter: uniform by area for a constant radiance, by the texture
    /// mapped onto the shape otherwise (as [`AreaEmitter::sample_direction`] does).
    pub fn sample_position(&self, u: Vec2, shapes: &[Shape], wl: Vec4) -> Option<EmitterPosition> {
        let geometry = &shapes[self.shape as usize].geometry;
        let pos = match &self.radiance {
            Texture::Constant { .. } | Texture::Spectral { .. } => {
                let ps = geometry.sample_position(u)?;
                let radiance = match &self.radiance {
                    Texture::Constant { rgb, .. } => from_rgb(*rgb),
                    t => t.eval(&TextureContext::at_uv_wl(Vec2::ZERO, wl)),
                };
                EmitterPosition {
                    p: ps.p,
                    p_error: ps.p_error,
                    n: ps.n,
                    ng: ps.n,
                    radiance,
                    pdf: ps.pdf,
                }
            }
            _ => {
                let (uv, pdf_uv) = self.radiance.sample_position(u);
                let si = geometry.at_uv(uv, self.uv_grid.as_ref(), self.shape)?;
                let jacobian = si.dp_du.cross(si.dp_dv).length();
                EmitterPosition {
                    p: si.p,
                    p_error: si.p_error,
                    n: si.frame.n,
                    ng: si.ng,
                    radiance: self.radiance.eval(&texture_context(&si, geometry, wl)),
                    pdf: pdf_uv / jacobian,
                }
            }
        };
        (pos.pdf.is_finite() && pos.pdf > 0.0).then_some(pos)
    }

    /// The area density with which [`AreaEmitter::sample_position`] draws the point `si`
    /// of the emitter's shape: uniform by area for a constant radiance, p_uv / |∂p/∂u ×
    /// ∂p/∂v| for a textured one.
    pub fn pdf_position(&self, si: &SurfaceInteraction, shapes: &[Shape]) -> f32 {
        let pdf = if !self.radiance.is_spatially_varying() {
            (1.0 / shapes[self.shape as usize].geometry.area()) as f32
        } else {
            let jacobian = si.dp_du.cross(si.dp_dv).length();
            self.radiance.pdf_position(si.uv) / jacobian
        };
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// The solid-angle density of [`AreaEmitter::sample_direction`] from `p_ref` where it
    /// samples the cone a sphere subtends (a constant radiance on a sphere seen from
    /// outside); `None` where it samples by area ([`AreaEmitter::pdf_position`]).
    pub fn cone_pdf(&self, p_ref: Vec3, shapes: &[Shape]) -> Option<f32> {
        if self.radiance.is_spatially_varying() {
            return None;
        }
        let ShapeGeometry::Sphere(s) = &shapes[self.shape as usize].geometry else {
            return None;
        };
        let (_, _, _, one_minus) = sphere_cone(s, p_ref)?;
        Some((1.0 / (2.0 * std::f64::consts::PI * one_minus)) as f32)
    }

    /// A ray leaving the emitter: a point by [`AreaEmitter::sample_position`] and a
    /// cosine-weighted direction on its emitting side, weight L π / p_A.
    pub fn sample_ray(
        &self,
        u_pos: Vec2,
        u_dir: Vec2,
        shapes: &[Shape],
        wl: Vec4,
    ) -> Option<EmitterRay> {
        let pos = self.sample_position(u_pos, shapes, wl)?;
        let d = Frame::from_normal(pos.n)
            .to_world(square_to_cosine_hemisphere(u_dir))
            .normalize();
        Some(EmitterRay {
            ray: Ray::new(
                offset_ray_origin(pos.p, pos.p_error, pos.ng, d),
                d,
                f32::INFINITY,
            ),
            weight: pos.radiance * (std::f32::consts::PI / pos.pdf),
            origin: pos.p,
            n: pos.n,
            ng: pos.ng,
            pdf_pos: pos.pdf,
        })
    }

    /// Solid-angle density with which `sample_direction` from `p_ref` yields the point of
    /// `si` (the same shape hit by a ray from `p_ref`).
    pub fn pdf_direction(&self, p_ref: Vec3, si: &SurfaceInteraction, shapes: &[Shape]) -> f32 {
        let geometry = &shapes[self.shape as usize].geometry;
        if self.radiance.is_spatially_varying() {
            let v = si.p - p_ref;
            let dist2 = v.length_squared();
            let cos_light = -si.ng.dot(v) / dist2.sqrt();
            let jacobian = si.dp_du.cross(si.dp_dv).length();
            if !(cos_light > 0.0 && jacobian > 0.0) {
                return 0.0;
            }
            let pdf = self.radiance.pdf_position(si.uv) * dist2 / (jacobian * cos_light);
            return if pdf.is_finite() { pdf } else { 0.0 };
        }
        if let ShapeGeometry::Sphere(s) = geometry {
            if let Some((_, _, _, one_minus)) = sphere_cone(s, p_ref) {
                return (1.0 / (2.0 * std::f64::consts::PI * one_minus)) as f32;
            }
        }
        let area = geometry.area();
        if area <= 0.0 {
            return 0.0;
        }
        let v = si.p - p_ref;
        let dist2 = v.length_squared();
        let cos_light = si.frame.n.dot(-v).abs() / dist2.sqrt();
        if cos_light == 0.0 {
            return 0.0;
        }
        (dist2 / (area as f32 * cos_light)).min(f32::MAX)
    }
}
