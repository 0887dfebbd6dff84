//! Rays, shading frames and robust ray spawning.
//!
//! Secondary and shadow rays start from a point offset along the geometric normal by the
//! hit point's conservative floating-point error bound, then rounded one ULP further away
//! (pbrt-v4, "Pharr, Jakob, Humphreys: Physically Based Rendering, 4th ed.", §6.8.6
//! "Robust spawned ray origins"). The offset is relative to the magnitude of the coordinates,
//! never a fixed epsilon, so the same scene renders alike at any scale or distance from the
//! origin. Shadow rays end short of their target by the relative margin [`SHADOW_EPSILON`].

use glam::Vec3;

/// Half an ULP of 1.0 in f32: the unit roundoff of IEEE-754 single precision.
pub const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// Relative margin by which a shadow ray stops short of its target point (its direction is
/// the unnormalised segment, so `t` runs from 0 to 1).
pub const SHADOW_EPSILON: f32 = 1e-4;

/// Higham's bound γ(n) = nε / (1 − nε) on the relative error of n chained roundings.
#[inline]
pub const fn gamma(n: i32) -> f32 {
    (n as f32 * MACHINE_EPSILON) / (1.0 - n as f32 * MACHINE_EPSILON)
}

/// The next representable f32 above `v` (∞ and NaN unchanged).
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 || v.is_nan() {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable f32 below `v`.
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    -next_float_up(-v)
}

/// A ray `o + t d` for `t` in `(0, tmax)`. `d` need not be normalised.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub tmax: f32,
}

impl Ray {
    pub fn new(o: Vec3, d: Vec3, tmax: f32) -> Self {
        Ray { o, d, tmax }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// Moves `p`, whose coordinates carry absolute error at most `p_error`, off the surface with
/// geometric normal `n` to the side that `w` points to, so that a ray leaving in direction `w`
/// cannot re-intersect the surface it starts on.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let mut po = p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = next_float_up(po[i]);
        } else if offset[i] < 0.0 {
            po[i] = next_float_down(po[i]);
        }
    }
    po
}

/// Mitsuba's `coordinate_system` in f64: two unit vectors completing the unit vector `n` to a
/// right-handed orthonormal basis (s, t, n), by the branchless construction of Duff et al.
/// 2017, "Building an Orthonormal Basis, Revisited" (JCGT 6(1)); [`Frame::from_normal`] is
/// the same in f32.
pub fn coordinate_system(n: glam::DVec3) -> (glam::DVec3, glam::DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        glam::DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        glam::DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// An orthonormal frame whose `n` axis is the local z axis (Mitsuba's `Frame3f`).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// The branchless orthonormal basis of Duff et al. 2017, "Building an Orthonormal Basis,
    /// Revisited" (JCGT 6(1)).
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// Mitsuba's shading frame (`SurfaceInteraction::initialize_sh_frame`): normal `n`, and
    /// the tangent `dp_du` made orthogonal to it (Gram–Schmidt), so that anisotropic BSDFs
    /// follow the surface's parameterisation. A zero `dp_du` falls back to
    /// [`Frame::from_normal`], as in Mitsuba; so does a `dp_du` parallel to `n` (Mitsuba gives
    /// NaN there).
    pub fn from_normal_tangent(n: Vec3, dp_du: Vec3) -> Self {
        let s = dp_du - n * n.dot(dp_du);
        // Scale first, so that tiny or huge tangents (scenes scaled by 1e±20) normalise.
        let m = s.abs().max_element();
        if !(m > 0.0 && m.is_finite()) {
            return Self::from_normal(n);
        }
        match (s / m).try_normalize() {
            Some(s) => Frame {
                s,
                t: n.cross(s),
                n,
            },
            None => Self::from_normal(n),
        }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal_for_all_hemispheres() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.4, 0.866).normalize(),
            Vec3::new(-1e-8, 0.0, -1.0).normalize(),
        ] {
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-6);
            assert!((f.t.length() - 1.0).abs() < 1e-6);
            assert!(f.s.dot(f.t).abs() < 1e-6 && f.s.dot(n).abs() < 1e-6);
            assert!((f.s.cross(f.t) - n).length() < 1e-5, "right-handed");
            let v = Vec3::new(0.2, -0.7, 0.4);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
    }

    #[test]
    fn next_float_steps_one_ulp() {
        assert_eq!(next_float_up(1.0), 1.0 + f32::EPSILON);
        assert_eq!(next_float_down(1.0), 1.0 - f32::EPSILON / 2.0);
        assert!(next_float_up(0.0) > 0.0 && next_float_up(-0.0) > 0.0);
        assert!(next_float_down(0.0) < 0.0);
        assert_eq!(next_float_up(-1.0), -1.0 + f32::EPSILON / 2.0);
    }

    #[test]
    fn offset_moves_to_the_side_of_w_by_at_least_the_error() {
        let p = Vec3::new(1e4, 2.0, -3e-3);
        let err = Vec3::splat(1e-3);
        let n = Vec3::Y;
        let up = offset_ray_origin(p, err, n, Vec3::new(0.1, 1.0, 0.0));
        let down = offset_ray_origin(p, err, n, Vec3::new(0.1, -1.0, 0.0));
        assert!(up.y > p.y + 1e-3 && down.y < p.y - 1e-3);
        assert_eq!(up.x, p.x);
    }
}
