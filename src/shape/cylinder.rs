//! Mitsuba's analytic `cylinder`: an open tube (no end caps) around the segment `p0`–`p1`
//! with radius `radius`, placed by `to_world`.
//!
//! # Mitsuba's conventions (read from src/shapes/cylinder.cpp, checked against Mitsuba 3.9.1
//! with validation/mitsuba/cylinder_hits.py)
//!
//! - **Object space.** Mitsuba bakes `p0`, `p1` and `radius` into one object-to-world matrix
//!   `M = to_world · translate(p0) · to_frame(Frame(d̂)) · scale(r, r, |d|)`, d = p1 − p0, and
//!   works on the unit cylinder x² + y² = 1, 0 ≤ z ≤ 1. `Frame(d̂)` is the Duff et al. basis
//!   (`coordinate_system`, as [`Frame::from_normal`]); its `s` axis is where φ = 0.
//! - **Intersection** is two-sided: rays from inside the tube hit its inner wall, and rays
//!   through the open ends hit the inside. A ray parallel to the axis never hits. Mitsuba
//!   intersects in object space in f64 (scalar variants), as here.
//! - **Normal** points away from the axis (outward), also for hits from inside, negated by
//!   `flip_normals`. Mitsuba computes it as normalize(dp/du × dp/dv) and, when M mirrors
//!   (det M < 0, which would turn that cross product inward), toggles `flip_normals`, so hit
//!   normals stay outward for mirrored transforms too.
//! - **uv** = (φ / 2π, z) with φ = atan2(y, x) ∈ [0, 2π) and z ∈ [0, 1] in object space (z = 0
//!   at p0, 1 at p1).
//! - **dp/du** = M · (2π · (−y, x, 0)) and **dp/dv** = M · (0, 0, 1) (world vectors, not
//!   normalised: |dp/du| = 2π · radius, |dp/dv| = the world length). The shading frame is
//!   Mitsuba's `sh_frame`: n as above, s = dp/du orthogonalised against n and normalised,
//!   t = n × s.
//! - **Area** = 2π · |M e_x| · |M e_z| (Mitsuba's `surface_area`); sampling is uniform in
//!   object space, `u.y` → φ = 2π u.y and `u.x` → z, with pdf 1 / area.
//! - **Transforms.** Mitsuba accepts any `to_world` but warns when M has shear or a
//!   different scale along object x and y ("non-uniform scaling along the X and Y axes"). A
//!   non-uniform scale along the cylinder's own axis is fine (it only changes the length). For
//!   the warned transforms Mitsuba still intersects the resulting elliptic or oblique tube
//!   exactly, but its area formula and constant pdf are then wrong (the sampled density is not
//!   uniform). penumbra does the same so that images agree, and reports the same warnings
//!   ([`Cylinder::warnings`]).
//!
//! # Where penumbra differs on purpose
//!
//! - For a mirrored `to_world` (det < 0) Mitsuba's `sample_position` returns *inward*
//!   normals (its toggled flip is applied to a normal transformed by the inverse transpose,
//!   which does not turn with the determinant), disagreeing with its own hit normals. Here
//!   sampled normals agree with hit normals (outward unless `flip_normals`).
//! - Rays must satisfy 0 < t < tmax strictly (Mitsuba accepts t = 0 and t = tmax).
//!
//! The hit point is re-projected onto the tube in object space (f64) before its final rounding
//! to f32, so its error bound `p_error` is that rounding plus a tiny f64 term: rays spawned
//! with [`offset_ray_origin`](crate::geometry::offset_ray_origin) start clear of the surface.

use super::{PositionSample, SurfaceInteraction};
use crate::geometry::{gamma, next_float_down, next_float_up, Frame, Ray};
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};
use std::f64::consts::PI;

/// Relative tolerance of the shear / non-uniform-scale checks behind [`Cylinder::warnings`]
/// (Mitsuba uses an absolute 1e-6 on the stretch matrix of its polar decomposition; a
/// relative one does not depend on the scene's scale).
const WARN_TOLERANCE: f64 = 1e-6;

#[derive(Clone, Debug)]
pub struct Cylinder {
    /// Object (unit cylinder) to world: Mitsuba's composed `m_to_world`.
    object_to_world: DMat4,
    world_to_object: DMat4,
    /// Inverse transpose of the linear part of `object_to_world`: maps object-space normals to
    /// world normals (before normalisation) without turning them for mirrors.
    normal_matrix: DMat3,
    /// Negate the outward normal (`flip_normals`).
    flip_normals: bool,
    /// |M e_x| and |M e_z|: Mitsuba's `m_radius` and `m_length`.
    radius: f64,
    length: f64,
    area: f64,
    sheared: bool,
    non_uniform_xy: bool,
}

impl Cylinder {
    /// The tube of radius `radius` around the segment `p0`–`p1` (object space of `to_world`),
    /// as Mitsuba's `cylinder` plugin builds it. `None` when degenerate: `p0 == p1`, radius 0,
    /// a singular `to_world`, or anything non-finite. A negative radius is allowed as in
    /// Mitsuba (the same tube, with φ measured from the opposite side).
    pub fn new(
        p0: DVec3,
        p1: DVec3,
        radius: f64,
        to_world: DMat4,
        flip_normals: bool,
    ) -> Option<Self> {
        let d = p1 - p0;
        let len = d.length();
        if !(len > 0.0 && len.is_finite() && radius != 0.0 && radius.is_finite()) {
            return None;
        }
        let n = d / len;
        let (s, t) = crate::geometry::coordinate_system(n);
        let frame = DMat4::from_cols(
            s.extend(0.0),
            t.extend(0.0),
            n.extend(0.0),
            DVec3::ZERO.extend(1.0),
        );
        let m = to_world
            * DMat4::from_translation(p0)
            * frame
            * DMat4::from_scale(DVec3::new(radius, radius, len));
        let lin = DMat3::from_mat4(m);
        let det = lin.determinant();
        let world_to_object = m.inverse();
        if !(det != 0.0 && det.is_finite() && m.is_finite() && world_to_object.is_finite()) {
            return None;
        }
        let (ex, ey, ez) = (lin.x_axis, lin.y_axis, lin.z_axis);
        let (radius, length) = (ex.length(), ez.length());
        let cos = |a: DVec3, b: DVec3| (a.dot(b) / (a.length() * b.length())).abs();
        let sheared = cos(ex, ey) > WARN_TOLERANCE
            || cos(ex, ez) > WARN_TOLERANCE
            || cos(ey, ez) > WARN_TOLERANCE;
        let (gx, gy) = (ex.length_squared(), ey.length_squared());
        let non_uniform_xy = (gx - gy).abs() > WARN_TOLERANCE * (gx + gy);
        Some(Cylinder {
            object_to_world: m,
            world_to_object,
            normal_matrix: lin.inverse().transpose(),
            flip_normals,
            radius,
            length,
            area: 2.0 * PI * radius * length,
            sheared,
            non_uniform_xy,
        })
    }

    /// Mitsuba's composed object-to-world matrix (unit tube, z ∈ [0, 1], to world).
    pub fn object_to_world(&self) -> DMat4 {
        self.object_to_world
    }

    /// Mitsuba's warnings about this cylinder's transform: shear, or different scales along
    /// the object x and y axes (an elliptic tube). Rendering goes on as in Mitsuba, but the
    /// area, and so the pdf of area sampling, is then only Mitsuba's approximation.
    pub fn warnings(&self) -> Vec<&'static str> {
        let mut w = Vec::new();
        if self.sheared {
            w.push("cylinder: 'to_world' transform shouldn't contain any shearing");
        }
        if self.non_uniform_xy {
            w.push(
                "cylinder: 'to_world' transform shouldn't contain non-uniform scaling along the \
                 X and Y axes (the area and the emitter sampling pdf will be wrong, as in Mitsuba)",
            );
        }
        w
    }

    /// Mitsuba's `surface_area`: 2π · world radius · world length (exact unless
    /// [`Cylinder::warnings`] is non-empty).
    pub fn area(&self) -> f64 {
        self.area
    }

    /// World radius |M e_x| and length |M e_z| (Mitsuba's `m_radius`, `m_length`).
    pub fn radius_length(&self) -> (f64, f64) {
        (self.radius, self.length)
    }

    /// Density of [`Cylinder::sample_position`] w.r.t. area: 1 / area (Mitsuba's
    /// `pdf_position`), the same at every point.
    pub fn pdf_position(&self) -> f32 {
        (1.0 / self.area) as f32
    }

    /// A conservative world-space bounding box: the box around the two end circles (Mitsuba's
    /// `bbox`), computed in f64 and rounded outward to f32.
    pub fn bounds(&self) -> [Vec3; 2] {
        let lin = DMat3::from_mat4(self.object_to_world);
        let (x1, x2) = (lin.x_axis, lin.y_axis);
        // Half extent of an ellipse c + x1 cos φ + x2 sin φ along each world axis.
        let half = (x1 * x1 + x2 * x2).map(f64::sqrt);
        let a = self.object_to_world.transform_point3(DVec3::ZERO);
        let b = self.object_to_world.transform_point3(DVec3::Z);
        let lo = (a.min(b) - half).as_vec3().to_array().map(next_float_down);
        let hi = (a.max(b) + half).as_vec3().to_array().map(next_float_up);
        [Vec3::from(lo), Vec3::from(hi)]
    }

    /// The ray in object space (the same parameter t) in f64.
    #[inline]
    fn to_object(&self, ray: &Ray) -> (DVec3, DVec3) {
        (
            self.world_to_object.transform_point3(ray.o.as_dvec3()),
            self.world_to_object.transform_vector3(ray.d.as_dvec3()),
        )
    }

    /// Closest hit 0 < t < ray.tmax (t in units of |ray.d|), from either side of the tube.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let (o, d) = self.to_object(ray);
        // x² + y² = 1 along the ray: a t² − 2 b t + c = 0, solved as for the sphere with the
        // discriminant of Haines et al. (Ray Tracing Gems ch. 7), b² − a c = a (1 − |l|²), l
        // the closest point of the projected line to the axis.
        let a = d.x * d.x + d.y * d.y;
        if a == 0.0 {
            return None; // parallel to the axis (or a zero direction)
        }
        let b = -(o.x * d.x + o.y * d.y);
        let (lx, ly) = (o.x + (b / a) * d.x, o.y + (b / a) * d.y);
        let disc = a * (1.0 - (lx * lx + ly * ly));
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let c = o.x * o.x + o.y * o.y - 1.0;
        let q = b + disc.sqrt().copysign(b);
        let (mut t0, mut t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q / a) };
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        for t in [t0, t1] {
            let t32 = t as f32;
            if t > 0.0 && t32 > 0.0 && t32 < ray.tmax {
                let z = o.z + t * d.z;
                if (0.0..=1.0).contains(&z) {
                    return Some(t32);
                }
            }
        }
        None
    }

    /// World point of the object-space point `local` (on the tube), rounded to f32, with a
    /// conservative bound on its error: the f32 rounding (γ(3)|p| leaves a margin over half
    /// an ULP) plus the f64 error of the re-projection and transform.
    fn world_point(&self, local: DVec3) -> (Vec3, Vec3) {
        let m = &self.object_to_world;
        let p = m.transform_point3(local);
        let lin = DMat3::from_mat4(*m);
        let abs = DMat3::from_cols(lin.x_axis.abs(), lin.y_axis.abs(), lin.z_axis.abs());
        let mag = abs * local.abs() + m.w_axis.truncate().abs();
        let err64 = (mag * (16.0 * f64::EPSILON)).as_vec3() * 2.0;
        let p32 = p.as_vec3();
        (p32, p32.abs() * gamma(3) + err64)
    }

    /// The unit world normal at the object-space point `local` (outward unless flipped).
    fn normal_at(&self, local: DVec3) -> DVec3 {
        let n = (self.normal_matrix * DVec3::new(local.x, local.y, 0.0)).normalize();
        if self.flip_normals {
            -n
        } else {
            n
        }
    }

    fn dp_du_local(&self, local: DVec3) -> DVec3 {
        self.object_to_world
            .transform_vector3(2.0 * PI * DVec3::new(-local.y, local.x, 0.0))
    }

    /// dp/du at the world point `p` on the tube: M · (2π (−y, x, 0)) with (x, y) the point's
    /// object coordinates (as Mitsuba derives it from `si.p`). Tangent to the circle through
    /// `p`, in the direction of growing φ, of length 2π · radius.
    pub fn dp_du(&self, p: Vec3) -> Vec3 {
        let local = self.world_to_object.transform_point3(p.as_dvec3());
        let r = (local.x * local.x + local.y * local.y).sqrt();
        let local = DVec3::new(local.x / r, local.y / r, local.z);
        self.dp_du_local(local).as_vec3()
    }

    /// dp/dv = M · (0, 0, 1): the world vector from p0 to p1, the same everywhere.
    pub fn dp_dv(&self) -> Vec3 {
        self.object_to_world.transform_vector3(DVec3::Z).as_vec3()
    }

    /// The surface interaction at a hit `t` returned by [`Cylinder::intersect`].
    pub fn interaction(&self, ray: &Ray, t: f32, shape: u32) -> SurfaceInteraction {
        let (o, d) = self.to_object(ray);
        let hit = o + d * t as f64;
        // Re-project onto the unit tube (the error left is f64 rounding).
        let r = (hit.x * hit.x + hit.y * hit.y).sqrt();
        self.interaction_at(DVec3::new(hit.x / r, hit.y / r, hit.z), t, shape)
    }

    /// The point with surface coordinates `uv` (Mitsuba's `eval_parameterization`:
    /// φ = 2π u, height v along the axis).
    pub fn at_uv(&self, uv: Vec2, shape: u32) -> SurfaceInteraction {
        let (sin_phi, cos_phi) = crate::math::sin_cos(2.0 * PI * uv.x as f64);
        self.interaction_at(DVec3::new(cos_phi, sin_phi, uv.y as f64), 0.0, shape)
    }

    /// The interaction at `local`, a point of the unit tube in object space.
    fn interaction_at(&self, local: DVec3, t: f32, shape: u32) -> SurfaceInteraction {
        let (p, p_error) = self.world_point(local);
        let n = self.normal_at(local);
        let dp_du = self.dp_du_local(local);
        let s = (dp_du - n * n.dot(dp_du)).normalize();
        let frame = Frame {
            s: s.as_vec3(),
            t: n.cross(s).as_vec3(),
            n: n.as_vec3(),
        };
        let mut phi = crate::math::atan2(local.y, local.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        SurfaceInteraction {
            p,
            p_error,
            t,
            ng: frame.n,
            frame,
            uv: Vec2::new((phi / (2.0 * PI)) as f32, local.z as f32),
            dp_du: dp_du.as_vec3(),
            dp_dv: self.dp_dv(),
            shape,
            prim: 0,
            bary: Vec2::ZERO,
        }
    }

    /// A point uniform in object space (φ = 2π u.y, z = u.x, as Mitsuba maps the sample), with
    /// pdf 1 / area w.r.t. world area (uniform in world area unless the transform is warned
    /// about).
    pub fn sample_position(&self, u: Vec2) -> PositionSample {
        let (sin, cos) = crate::math::sin_cos(2.0 * PI * u.y as f64);
        let local = DVec3::new(cos, sin, u.x as f64);
        let (p, p_error) = self.world_point(local);
        PositionSample {
            p,
            p_error,
            n: self.normal_at(local).as_vec3(),
            pdf: self.pdf_position(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::offset_ray_origin;
    use crate::study::stats::chi2_sf;
    use rand::{RngExt, SeedableRng};

    /// Mitsuba 3.9.1's numbers, from validation/mitsuba/cylinder_hits.py.
    const MITSUBA: &str = include_str!("../../tests/data/mitsuba_cylinder_hits.txt");

    struct Case {
        name: String,
        flip: bool,
        p0: DVec3,
        p1: DVec3,
        radius: f64,
        to_world: DMat4,
        object: DMat4,
        area: f64,
        bbox: [Vec3; 2],
        /// (kind, ray, Mitsuba's hit record or None for a miss)
        rays: Vec<(String, Ray, Option<Vec<f32>>)>,
        /// u.xy, p.xyz, n.xyz, pdf, pdf_position
        samples: Vec<Vec<f32>>,
    }

    impl Case {
        fn cylinder(&self) -> Cylinder {
            Cylinder::new(self.p0, self.p1, self.radius, self.to_world, self.flip).unwrap()
        }
    }

    fn nums<T: std::str::FromStr>(s: &str) -> Vec<T>
    where
        T::Err: std::fmt::Debug,
    {
        s.split_whitespace().map(|x| x.parse().unwrap()).collect()
    }

    fn rows_to_mat(v: &[f64]) -> DMat4 {
        DMat4::from_cols_array(v.try_into().unwrap()).transpose()
    }

    fn parse() -> Vec<Case> {
        let mut cases: Vec<Case> = Vec::new();
        for line in MITSUBA.lines().filter(|l| !l.starts_with('#')) {
            let (tag, rest) = line.split_once(' ').unwrap();
            if tag == "case" {
                let w: Vec<&str> = rest.split_whitespace().collect();
                cases.push(Case {
                    name: w[0].to_string(),
                    flip: w[2] == "1",
                    p0: DVec3::ZERO,
                    p1: DVec3::ZERO,
                    radius: 0.0,
                    to_world: DMat4::IDENTITY,
                    object: DMat4::IDENTITY,
                    area: 0.0,
                    bbox: [Vec3::ZERO; 2],
                    rays: Vec::new(),
                    samples: Vec::new(),
                });
                continue;
            }
            let c = cases.last_mut().unwrap();
            match tag {
                "p0" => c.p0 = DVec3::from_slice(&nums::<f64>(rest)),
                "p1" => c.p1 = DVec3::from_slice(&nums::<f64>(rest)),
                "radius" => c.radius = nums::<f64>(rest)[0],
                "to_world" => c.to_world = rows_to_mat(&nums::<f64>(rest)),
                "object" => c.object = rows_to_mat(&nums::<f64>(rest)),
                "area" => c.area = nums::<f64>(rest)[0],
                "bbox" => {
                    let v = nums::<f32>(rest);
                    c.bbox = [Vec3::from_slice(&v[..3]), Vec3::from_slice(&v[3..])];
                }
                "r" => {
                    let (kind, rest) = rest.split_once(' ').unwrap();
                    let (ray, hit) = match rest.strip_suffix(" miss") {
                        Some(r) => (nums::<f32>(r), None),
                        None => {
                            let v = nums::<f32>(rest);
                            (v[..7].to_vec(), Some(v[7..].to_vec()))
                        }
                    };
                    let ray = Ray::new(
                        Vec3::from_slice(&ray[..3]),
                        Vec3::from_slice(&ray[3..6]),
                        ray[6],
                    );
                    c.rays.push((kind.to_string(), ray, hit));
                }
                "s" => c.samples.push(nums::<f32>(rest)),
                _ => panic!("bad line {line}"),
            }
        }
        assert_eq!(cases.len(), 4);
        cases
    }

    fn v3(v: &[f32]) -> Vec3 {
        Vec3::from_slice(&v[..3])
    }

    /// Mitsuba builds its matrices in f32 and transforms each ray into object space with an
    /// f32 inverse (relative error a few ε_f32 ≈ 1e-7 times the condition number of M,
    /// below 8 in these cases), so its hit distances and points carry relative errors of
    /// ~1e-6 (largest seen: 2e-6, in normals); penumbra works in f64. 1e-5 leaves a 5x
    /// margin. Grazing rays pass at object distance 1 − 1e-3 from the axis, where the root's
    /// sensitivity to the ray is amplified by 1 / sqrt(1 − 0.999²) ≈ 22: 25x the tolerance
    /// there (largest seen: 1.5e-5).
    const TOL: f32 = 1e-5;

    #[test]
    fn object_matrix_area_and_bounds_match_mitsuba() {
        for c in parse() {
            let cyl = c.cylinder();
            let scale = c
                .object
                .to_cols_array()
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()));
            let diff = (cyl.object_to_world() - c.object)
                .to_cols_array()
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(
                diff < 1e-6 * scale,
                "{}: object matrix off by {diff}",
                c.name
            );
            assert!(
                ((cyl.area() - c.area) / c.area).abs() < 1e-6,
                "{}: area {} vs Mitsuba {}",
                c.name,
                cyl.area(),
                c.area
            );
            let [lo, hi] = cyl.bounds();
            let bscale = c.bbox[0].abs().max(c.bbox[1].abs()).max_element();
            assert!(
                (lo - c.bbox[0]).abs().max_element() < TOL * bscale
                    && (hi - c.bbox[1]).abs().max_element() < TOL * bscale,
                "{}: bounds {lo} {hi} vs Mitsuba {:?}",
                c.name,
                c.bbox
            );
            let expect_warn = c.name == "elliptic";
            assert_eq!(!cyl.warnings().is_empty(), expect_warn, "{}", c.name);
        }
    }

    #[test]
    fn hits_match_mitsuba() {
        let mut hits = 0;
        let mut misses = 0;
        for c in parse() {
            let cyl = c.cylinder();
            let r_world = cyl.radius_length().0 as f32;
            for (i, (kind, ray, expect)) in c.rays.iter().enumerate() {
                let ctx = format!("{} ray {i} ({kind})", c.name);
                let got = cyl.intersect(ray);
                let Some(m) = expect else {
                    assert!(got.is_none(), "{ctx}: hit at {got:?}, Mitsuba misses");
                    misses += 1;
                    continue;
                };
                hits += 1;
                let t = got.unwrap_or_else(|| panic!("{ctx}: miss, Mitsuba hits at t = {}", m[0]));
                let tol = if kind == "graze-in" { 25.0 * TOL } else { TOL };
                let si = cyl.interaction(ray, t, 7);
                assert_eq!(si.shape, 7);
                let (mt, mp, mn, msh_n, msh_s) =
                    (m[0], v3(&m[1..]), v3(&m[4..]), v3(&m[7..]), v3(&m[10..]));
                let (muv, mdpdu, mdpdv) = (Vec2::new(m[13], m[14]), v3(&m[15..]), v3(&m[18..]));
                assert!((t - mt).abs() <= tol * mt, "{ctx}: t {t} vs {mt}");
                let pscale = mp.abs().max_element().max(r_world);
                assert!(
                    (si.p - mp).abs().max_element() <= tol * pscale,
                    "{ctx}: p {} vs {mp}",
                    si.p
                );
                assert!(
                    (si.ng - mn).abs().max_element() <= tol,
                    "{ctx}: n {} vs {mn}",
                    si.ng
                );
                assert!(
                    (si.frame.n - msh_n).abs().max_element() <= tol,
                    "{ctx}: sh_n"
                );
                assert!(
                    (si.frame.s - msh_s).abs().max_element() <= tol,
                    "{ctx}: sh_s {} vs {msh_s}",
                    si.frame.s
                );
                assert!(
                    (si.frame.t - si.frame.n.cross(si.frame.s)).length() < 1e-6,
                    "{ctx}: right-handed frame"
                );
                // u wraps at φ = 0 ≡ 2π.
                let du = (si.uv.x - muv.x).abs();
                assert!(
                    du.min(1.0 - du) <= tol && (si.uv.y - muv.y).abs() <= tol,
                    "{ctx}: uv {} vs {muv}",
                    si.uv
                );
                let dp_du = cyl.dp_du(si.p);
                assert!(
                    (dp_du - mdpdu).abs().max_element() <= tol * mdpdu.length(),
                    "{ctx}: dp_du {dp_du} vs {mdpdu}"
                );
                let dp_dv = cyl.dp_dv();
                assert!(
                    (dp_dv - mdpdv).abs().max_element() <= tol * mdpdv.length(),
                    "{ctx}: dp_dv {dp_dv} vs {mdpdv}"
                );
            }
        }
        assert!(hits >= 60 && misses >= 40, "{hits} hits, {misses} misses");
    }

    #[test]
    fn samples_and_pdf_match_mitsuba() {
        for c in parse() {
            let cyl = c.cylinder();
            let r_world = cyl.radius_length().0 as f32;
            for s in &c.samples {
                let ps = cyl.sample_position(Vec2::new(s[0], s[1]));
                let (mp, mn, mpdf, mpdf_pos) = (v3(&s[2..]), v3(&s[5..]), s[8], s[9]);
                let pscale = mp.abs().max_element().max(r_world);
                assert!(
                    (ps.p - mp).abs().max_element() <= TOL * pscale,
                    "{}: p {} vs {mp}",
                    c.name,
                    ps.p
                );
                // penumbra keeps sampled normals outward for a mirrored to_world, where Mitsuba
                // returns inward ones (see the module docs).
                let mn = if c.name == "mirrored" { -mn } else { mn };
                assert!(
                    (ps.n - mn).abs().max_element() <= TOL,
                    "{}: n {} vs {mn}",
                    c.name,
                    ps.n
                );
                assert!(
                    (ps.pdf - mpdf).abs() <= 1e-6 * mpdf
                        && (cyl.pdf_position() - mpdf_pos).abs() <= 1e-6 * mpdf
                );
            }
        }
    }

    #[test]
    fn mirrored_samples_face_like_hit_normals() {
        let c = parse().into_iter().find(|c| c.name == "mirrored").unwrap();
        let cyl = c.cylinder();
        let axis_o = cyl.object_to_world().transform_point3(DVec3::ZERO);
        let axis_d = cyl
            .object_to_world()
            .transform_vector3(DVec3::Z)
            .normalize();
        for i in 0..16 {
            let ps = cyl.sample_position(Vec2::new(0.5, i as f32 / 16.0));
            let v = ps.p.as_dvec3() - axis_o;
            let radial = v - axis_d * v.dot(axis_d);
            assert!(radial.dot(ps.n.as_dvec3()) > 0.0, "outward");
        }
    }

    /// World-space (φ, h) of a point: angle around the world axis p0→p1 from an arbitrary
    /// reference direction, and the fraction of the way from p0 to p1. Independent of the
    /// cylinder's object space.
    fn world_cylindrical(p: DVec3, p0: DVec3, p1: DVec3) -> (f64, f64, f64) {
        let axis = p1 - p0;
        let len = axis.length();
        let a = axis / len;
        let r = a.any_orthonormal_vector();
        let s = a.cross(r);
        let v = p - p0;
        let h = v.dot(a) / len;
        let radial = v - a * v.dot(a);
        let phi = radial.dot(s).atan2(radial.dot(r)).rem_euclid(2.0 * PI);
        (phi, h, radial.length())
    }

    #[test]
    fn sampled_points_are_uniform_on_the_surface() {
        // Proper cylinders (uniform scale across the axis, no shear), one flipped and scaled
        // along its axis. A 16x16 grid over world (φ, h) has cells of equal area, so each
        // expects n / 256 samples.
        let cases = [
            (
                DVec3::new(0.2, -0.4, 0.1),
                DVec3::new(-0.6, 0.8, 1.9),
                0.45,
                false,
                DMat4::from_translation(DVec3::new(1.0, 2.0, -3.0))
                    * DMat4::from_axis_angle(DVec3::new(1.0, 1.0, 0.0).normalize(), 0.6)
                    * DMat4::from_scale(DVec3::splat(1.3)),
            ),
            (
                DVec3::new(0.0, 0.0, -0.5),
                DVec3::new(0.0, 0.0, 1.0),
                0.6,
                true,
                DMat4::from_axis_angle(DVec3::new(0.2, 1.0, 0.3).normalize(), 1.2)
                    * DMat4::from_scale(DVec3::new(0.8, 0.8, 2.5)),
            ),
        ];
        let mut rng = rand_pcg::Pcg32::seed_from_u64(17);
        let (nphi, nh, n) = (16usize, 16usize, 256_000usize);
        for (p0, p1, radius, flip, to_world) in cases {
            let cyl = Cylinder::new(p0, p1, radius, to_world, flip).unwrap();
            assert!(cyl.warnings().is_empty());
            let (w0, w1) = (to_world.transform_point3(p0), to_world.transform_point3(p1));
            let r_world = cyl.radius_length().0;
            let mut counts = vec![0usize; nphi * nh];
            for _ in 0..n {
                let u = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
                let ps = cyl.sample_position(u);
                assert!((ps.pdf as f64 * cyl.area() - 1.0).abs() < 1e-6);
                let (phi, h, r) = world_cylindrical(ps.p.as_dvec3(), w0, w1);
                assert!((r - r_world).abs() < 1e-5 * (1.0 + r_world), "on the tube");
                assert!((-1e-6..=1.0 + 1e-6).contains(&h));
                let i = ((phi / (2.0 * PI) * nphi as f64) as usize).min(nphi - 1);
                let j = ((h * nh as f64) as usize).min(nh - 1);
                counts[j * nphi + i] += 1;
            }
            let expected = n as f64 / counts.len() as f64;
            let chi2: f64 = counts
                .iter()
                .map(|&c| (c as f64 - expected).powi(2) / expected)
                .sum();
            let dof = (counts.len() - 1) as f64;
            // Two tests at alpha 0.01 overall (Sidak): each must have p > 1 - 0.99^(1/2).
            let p = chi2_sf(chi2, dof);
            assert!(p > 1.0 - 0.99f64.sqrt(), "chi2 {chi2} (dof {dof}), p = {p}");
        }
    }

    #[test]
    fn spawned_rays_do_not_rehit_at_the_origin() {
        // (p0, p1, radius, to_world): plain, tiny and far, huge, and a flipped mirror.
        let cases = [
            (DVec3::ZERO, DVec3::Z, 1.0, DMat4::IDENTITY, false),
            (
                DVec3::new(0.0, 0.0, -1e-3),
                DVec3::new(1e-3, 2e-3, 1e-3),
                1e-3,
                DMat4::from_translation(DVec3::new(100.0, -50.0, 20.0)),
                false,
            ),
            (
                DVec3::new(-1.0, 0.0, 0.0),
                DVec3::new(1.0, 0.5, 0.0),
                1e3,
                DMat4::from_axis_angle(DVec3::Y, 0.3),
                true,
            ),
            (
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 3.0),
                2.0,
                DMat4::from_translation(DVec3::new(1e4, 0.0, -3e3))
                    * DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0)),
                true,
            ),
        ];
        let mut rng = rand_pcg::Pcg32::seed_from_u64(99);
        let unit = |rng: &mut rand_pcg::Pcg32| loop {
            let v = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        };
        let (mut checked_hits, mut checked_outward) = (0, 0);
        for (p0, p1, radius, to_world, flip) in cases {
            let cyl = Cylinder::new(p0, p1, radius, to_world, flip).unwrap();
            let m = cyl.object_to_world();
            let w2o = m.inverse();
            for k in 0..400 {
                // A primary ray from outside (even k) or from inside the tube (odd k) to a
                // random point of the wall.
                let phi = rng.random_range(0.0..2.0 * PI);
                let z = rng.random_range(0.02..0.98);
                let target = m.transform_point3(DVec3::new(phi.cos(), phi.sin(), z));
                let from = if k % 2 == 0 {
                    let a = phi + rng.random_range(-1.0..1.0);
                    DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), rng.random_range(0.0..1.0))
                } else {
                    DVec3::new(
                        rng.random_range(-0.5..0.5),
                        rng.random_range(-0.5..0.5),
                        0.5,
                    )
                };
                let o = m.transform_point3(from);
                let ray = Ray::new(o.as_vec3(), (target - o).as_vec3(), f32::INFINITY);
                let Some(t) = cyl.intersect(&ray) else {
                    continue;
                };
                let si = cyl.interaction(&ray, t, 0);
                let local = w2o.transform_point3(si.p.as_dvec3());
                let q = DVec3::new(local.x, local.y, 0.0).normalize();
                let n_out = (cyl.normal_matrix * q).normalize();
                for _ in 0..8 {
                    let w = unit(&mut rng);
                    let o2 = offset_ray_origin(si.p, si.p_error, si.ng, w.as_vec3());
                    let spawned = Ray::new(o2, w.as_vec3(), f32::INFINITY);
                    let hit = cyl.intersect(&spawned);
                    let cos = w.dot(n_out);
                    if cos > 0.0 {
                        // Leaving the (convex) tube: nothing to hit.
                        assert!(
                            hit.is_none(),
                            "outward ray re-hit at t = {hit:?} (cos {cos})"
                        );
                        checked_outward += 1;
                        continue;
                    }
                    if cos > -0.2 {
                        continue; // too close to tangent for the chord check below
                    }
                    // Into the tube: the far wall, at the other root of the line from the
                    // surface point. The spawned origin sits |o2 − p| off the surface, which
                    // moves that root by up to about |o2 − p| / |cos| (with a 2x margin);
                    // a re-hit of the starting point would be at t ≈ |o2 − p| instead.
                    let dl = w2o.transform_vector3(w);
                    let tc = -2.0 * (q.x * dl.x + q.y * dl.y) / (dl.x * dl.x + dl.y * dl.y);
                    let off = (o2 - si.p).length() as f64;
                    let slack = 2.0 * off / -cos + 1e-4 * tc;
                    if tc <= 2.0 * slack {
                        // f32 positions far from the origin of a tiny tube: the offset is a
                        // good fraction of the radius and the check would say little.
                        continue;
                    }
                    let (z_lo, z_hi) = {
                        let (a, b) = (local.z + (tc - slack) * dl.z, local.z + (tc + slack) * dl.z);
                        (a.min(b), a.max(b))
                    };
                    if z_lo > 0.0 && z_hi < 1.0 {
                        let t2 = hit.unwrap_or_else(|| panic!("missed the far wall at {tc}"));
                        assert!(
                            (t2 as f64 - tc).abs() <= slack,
                            "hit at t = {t2}, the far wall is at {tc} ± {slack}"
                        );
                        checked_hits += 1;
                    } else if z_hi < 0.0 || z_lo > 1.0 {
                        assert!(hit.is_none(), "leaves through an end, hit at {hit:?}");
                    }
                }
            }
        }
        assert!(
            checked_hits > 1000 && checked_outward > 2000,
            "{checked_hits} {checked_outward}"
        );
    }

    #[test]
    fn default_cylinder_conventions() {
        let c = Cylinder::new(DVec3::ZERO, DVec3::Z, 1.0, DMat4::IDENTITY, false).unwrap();
        assert!((c.area() - 2.0 * PI).abs() < 1e-12);
        // From outside along -x: hits (1, 0, 0.5), normal +x, uv (0, 0.5).
        let r = Ray::new(Vec3::new(3.0, 0.0, 0.5), -Vec3::X, f32::INFINITY);
        let si = c.interaction(&r, c.intersect(&r).unwrap(), 0);
        assert!((si.p - Vec3::new(1.0, 0.0, 0.5)).length() < 1e-6);
        assert!((si.ng - Vec3::X).length() < 1e-6);
        assert!(si.uv.abs_diff_eq(Vec2::new(0.0, 0.5), 1e-6));
        assert!((c.dp_du(si.p) - Vec3::new(0.0, 2.0 * PI as f32, 0.0)).length() < 1e-5);
        // From the axis towards +y: the inner wall at (0, 1), normal still outward (+y).
        let r = Ray::new(Vec3::new(0.0, 0.0, 0.25), Vec3::Y, f32::INFINITY);
        let si = c.interaction(&r, c.intersect(&r).unwrap(), 0);
        assert!((si.t - 1.0).abs() < 1e-6 && (si.ng - Vec3::Y).length() < 1e-6);
        assert!(si.uv.abs_diff_eq(Vec2::new(0.25, 0.25), 1e-6));
        // No caps: along the axis, and through both open ends, nothing is hit.
        assert!(c
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, f32::INFINITY))
            .is_none());
        assert!(c
            .intersect(&Ray::new(
                Vec3::new(0.1, 0.0, -1.0),
                Vec3::new(0.0, 0.01, 1.0),
                f32::INFINITY
            ))
            .is_none());
        let f = Cylinder::new(DVec3::ZERO, DVec3::Z, 1.0, DMat4::IDENTITY, true).unwrap();
        let r = Ray::new(Vec3::new(3.0, 0.0, 0.5), -Vec3::X, f32::INFINITY);
        assert!(
            (f.interaction(&r, 2.0, 0).ng + Vec3::X).length() < 1e-6,
            "flipped"
        );
        assert!(f
            .sample_position(Vec2::new(0.5, 0.0))
            .n
            .abs_diff_eq(-Vec3::X, 1e-6));
        // Degenerate inputs.
        assert!(Cylinder::new(DVec3::ONE, DVec3::ONE, 1.0, DMat4::IDENTITY, false).is_none());
        assert!(Cylinder::new(DVec3::ZERO, DVec3::Z, 0.0, DMat4::IDENTITY, false).is_none());
        let flat = DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0));
        assert!(Cylinder::new(DVec3::ZERO, DVec3::Z, 1.0, flat, false).is_none());
    }
}
