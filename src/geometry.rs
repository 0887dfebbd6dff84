//! Rays, shading frames and robust ray spawning.
//!
//! Secondary and shadow rays start from a point offset along the geometric normal by the
//! hit point's conservative floating-point error bound, then rounded one ULP further away
//! (pbrt-v4, "Pharr, Jakob, Humphreys: Physically Based Rendering, 4th ed.", §6.8.6
//! "Robust spawned ray origins"). The offset is relative to the magnitude of the coordinates,
//! never a fixed epsilon, so the same scene renders alike at any scale or distance from the
//! origin. Shadow rays end short of their target by the relative margin [`SHADOW_EPSILON`].

use crate::simd::{LaneF32, LaneMask, LaneU32, Lanes, Scalar, V3};
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

/// Rays in lanes ([`Ray`] per lane).
#[derive(Clone, Copy, Debug)]
pub struct Rays<L: Lanes> {
    pub o: V3<L::F>,
    pub d: V3<L::F>,
    pub tmax: L::F,
}

impl<L: Lanes> Rays<L> {
    /// Lane `i`'s ray.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Ray {
        Ray::new(self.o.lane(i), self.d.lane(i), self.tmax.lane(i))
    }
}

impl From<Ray> for Rays<Scalar> {
    #[inline(always)]
    fn from(r: Ray) -> Rays<Scalar> {
        Rays {
            o: r.o.into(),
            d: r.d.into(),
            tmax: r.tmax,
        }
    }
}

impl From<Rays<Scalar>> for Ray {
    #[inline(always)]
    fn from(r: Rays<Scalar>) -> Ray {
        Ray::new(r.o.into(), r.d.into(), r.tmax)
    }
}

/// Moves `p`, whose coordinates carry absolute error at most `p_error`, off the surface with
/// geometric normal `n` to the side that `w` points to, so that a ray leaving in direction `w`
/// cannot re-intersect the surface it starts on. The width-1 instance of
/// [`offset_ray_origin_lanes`].
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    offset_ray_origin_lanes(Scalar, p.into(), p_error.into(), n.into(), w.into()).into()
}

/// [`offset_ray_origin`] lane by lane, written once for every lane backend (issue 42): the
/// offset n · (|n| · p_error), negated where w · n < 0, added to `p`, and each coordinate
/// then stepped one ULP further in the direction of its offset ([`next_float_up`] or
/// [`next_float_down`]; unchanged where the offset is 0 or NaN).
#[inline(always)]
pub fn offset_ray_origin_lanes<L: Lanes>(
    l: L,
    p: V3<L::F>,
    p_error: V3<L::F>,
    n: V3<L::F>,
    w: V3<L::F>,
) -> V3<L::F> {
    let d = n.abs().dot(p_error);
    // −(n d) = n (−d) bit for bit (a product's sign is the sign of its factors' product,
    // its magnitude rounded alike): one select, not three.
    let flip = w.dot(n).cmp_lt(l.splat(0.0));
    let offset = n * L::F::select(flip, -d, d);
    let po = p + offset;
    V3::new(
        step_away(l, po.x, offset.x),
        step_away(l, po.y, offset.y),
        step_away(l, po.z, offset.z),
    )
}

/// `x` stepped one ULP up where `offset > 0`, down where `offset < 0`, else unchanged: the
/// per-coordinate rounding of [`offset_ray_origin`]. A step down is −next_float_up(−x), as
/// [`next_float_down`] is.
#[inline(always)]
fn step_away<L: Lanes>(l: L, x: L::F, offset: L::F) -> L::F {
    let zero = l.splat(0.0);
    let up = offset.cmp_gt(zero);
    let down = offset.cmp_lt(zero);
    let moved = up | down;
    if !moved.any() {
        return x;
    }
    let s = L::F::select(down, -x, x);
    let r = next_float_up_lanes(l, s);
    let r = L::F::select(down, -r, r);
    L::F::select(moved, r, x)
}

/// [`next_float_up`] lane by lane.
#[inline(always)]
pub fn next_float_up_lanes<L: Lanes>(l: L, v: L::F) -> L::F {
    let zero = l.splat(0.0);
    let keep = v.cmp_eq(l.splat(f32::INFINITY)) | v.is_nan();
    // ±0 both step from +0
    let v0 = L::F::select(v.cmp_eq(zero), zero, v);
    let bits = v0.to_bits();
    let one = l.splat_u32(1);
    let stepped = L::U32::select(
        v0.cmp_ge(zero),
        bits.wrapping_add(one),
        bits.wrapping_sub(one),
    );
    L::F::select(keep, v, L::F::from_bits(stepped))
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
    /// Revisited" (JCGT 6(1)). The width-1 instance of [`Frames::from_normal`].
    pub fn from_normal(n: Vec3) -> Self {
        Frames::from_normal(Scalar, n.into()).into()
    }

    /// Mitsuba's shading frame (`SurfaceInteraction::initialize_sh_frame`): normal `n`, and
    /// the tangent `dp_du` made orthogonal to it (Gram–Schmidt), so that anisotropic BSDFs
    /// follow the surface's parameterisation. A zero `dp_du` falls back to
    /// [`Frame::from_normal`], as in Mitsuba; so does a `dp_du` parallel to `n` (Mitsuba gives
    /// NaN there). The width-1 instance of [`Frames::from_normal_tangent`].
    pub fn from_normal_tangent(n: Vec3, dp_du: Vec3) -> Self {
        Frames::from_normal_tangent(Scalar, n.into(), dp_du.into()).into()
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

/// Frames in lanes ([`Frame`] per lane).
#[derive(Clone, Copy, Debug)]
pub struct Frames<L: Lanes> {
    pub s: V3<L::F>,
    pub t: V3<L::F>,
    pub n: V3<L::F>,
}

impl<L: Lanes> Frames<L> {
    /// [`Frame::from_normal`] lane by lane: s = (1 + σ n_x² a, σ b, −σ n_x),
    /// t = (b, σ + n_y² a, −n_y) with σ = ±1 the sign of n_z, a = −1 / (σ + n_z),
    /// b = n_x n_y a.
    #[inline(always)]
    pub fn from_normal(l: L, n: V3<L::F>) -> Self {
        let one = l.splat(1.0);
        let sign = one.copysign(n.z);
        let a = -one / (sign + n.z);
        let b = n.x * n.y * a;
        Frames {
            s: V3::new(one + sign * n.x * n.x * a, sign * b, -sign * n.x),
            t: V3::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }

    /// [`Frame::from_normal_tangent`] lane by lane: s = dp_du − n (n · dp_du), scaled by
    /// its largest |component| and normalised (glam's `try_normalize`), t = n × s; the
    /// frame of [`Frames::from_normal`] where that fails.
    #[inline(always)]
    pub fn from_normal_tangent(l: L, n: V3<L::F>, dp_du: V3<L::F>) -> Self {
        let zero = l.splat(0.0);
        let s = dp_du - n * n.dot(dp_du);
        // Scale first, so that tiny or huge tangents (scenes scaled by 1e±20) normalise.
        let m = s.abs().max_element();
        let scaled = m.cmp_gt(zero) & m.is_finite();
        let s = s / m;
        let rcp = l.splat(1.0) / s.length();
        let ok = scaled & rcp.is_finite() & rcp.cmp_gt(zero);
        let s = s * rcp;
        let frame = Frames {
            s,
            t: n.cross(s),
            n,
        };
        let fallback = !ok;
        if !fallback.any() {
            return frame;
        }
        Frames::select(fallback, &Frames::from_normal(l, n), &frame)
    }

    /// `if m { a } else { b }` lane by lane.
    #[inline(always)]
    pub fn select(m: L::M, a: &Self, b: &Self) -> Self {
        Frames {
            s: V3::select(m, a.s, b.s),
            t: V3::select(m, a.t, b.t),
            n: V3::select(m, a.n, b.n),
        }
    }

    /// [`Frame::to_local`] lane by lane: (v · s, v · t, v · n).
    #[inline(always)]
    pub fn to_local(&self, v: V3<L::F>) -> V3<L::F> {
        V3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// [`Frame::to_world`] lane by lane: (s v_x + t v_y) + n v_z.
    #[inline(always)]
    pub fn to_world(&self, v: V3<L::F>) -> V3<L::F> {
        self.s * v.x + self.t * v.y + self.n * v.z
    }

    #[inline(always)]
    pub fn lane(&self, i: usize) -> Frame {
        Frame {
            s: self.s.lane(i),
            t: self.t.lane(i),
            n: self.n.lane(i),
        }
    }

    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, f: &Frame) {
        self.s.set_lane(i, f.s);
        self.t.set_lane(i, f.t);
        self.n.set_lane(i, f.n);
    }
}

impl From<Frame> for Frames<Scalar> {
    #[inline(always)]
    fn from(f: Frame) -> Self {
        Frames {
            s: f.s.into(),
            t: f.t.into(),
            n: f.n.into(),
        }
    }
}

impl From<Frames<Scalar>> for Frame {
    #[inline(always)]
    fn from(f: Frames<Scalar>) -> Self {
        Frame {
            s: f.s.into(),
            t: f.t.into(),
            n: f.n.into(),
        }
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

    /// The scalar offset as it was before the lane kernel (issue 42, step 3a): the oracle
    /// that [`offset_ray_origin_lanes`] must reproduce bit for bit on every backend.
    fn offset_reference(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
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

    /// Same bits, or NaN where the reference is NaN (a computed NaN's payload is not
    /// specified, see `simd`).
    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || a.is_nan() && b.is_nan()
    }

    /// Random offset inputs with the edges: axis-aligned normals (exact zeros in the
    /// offset), ±0 coordinates, directions perpendicular to the normal (w · n = 0),
    /// subnormals, huge and infinite coordinates, NaNs, zero error bounds.
    fn offset_cases() -> Vec<[Vec3; 4]> {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(0x0ff5e7);
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e-40,
            -1e-40,
            f32::MIN_POSITIVE,
            3.0e38,
            -3.0e38,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            16777216.0,
            -0.5,
        ];
        let x = |rng: &mut rand_pcg::Pcg32| match rng.random_range(0..5) {
            0 => special[rng.random_range(0..special.len())],
            1 => rng.random_range(-1e4f32..1e4),
            2 => rng.random_range(-1.0f32..1.0) * 1e-30,
            _ => rng.random_range(-2.0f32..2.0),
        };
        let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z];
        (0..16 * 4096)
            .map(|_| {
                let p = Vec3::new(x(&mut rng), x(&mut rng), x(&mut rng));
                let e = Vec3::new(x(&mut rng), x(&mut rng), x(&mut rng)).abs()
                    * if rng.random_range(0..4) == 0 {
                        0.0
                    } else {
                        1e-6
                    };
                let n = match rng.random_range(0..4) {
                    0 => axes[rng.random_range(0..6)],
                    1 => Vec3::new(x(&mut rng), x(&mut rng), x(&mut rng)),
                    _ => Vec3::new(
                        rng.random_range(-1.0f32..1.0),
                        rng.random_range(-1.0f32..1.0),
                        rng.random_range(-1.0f32..1.0),
                    )
                    .normalize_or_zero(),
                };
                let w = match rng.random_range(0..4) {
                    // perpendicular: w · n = 0 exactly for axis-aligned n
                    0 => n.any_orthogonal_vector(),
                    1 => -n,
                    _ => Vec3::new(x(&mut rng), x(&mut rng), x(&mut rng)),
                };
                [p, e, n, w]
            })
            .collect()
    }

    struct OffsetProgram<'a>(&'a [[Vec3; 4]]);

    impl crate::simd::LaneProgram for OffsetProgram<'_> {
        type Output = Vec<Vec3>;
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Vec<Vec3> {
            let mut out = Vec::with_capacity(self.0.len());
            for chunk in self.0.chunks(L::WIDTH) {
                let mut v = [V3::splat(l.splat(0.0)); 4];
                for (i, c) in chunk.iter().enumerate() {
                    for k in 0..4 {
                        v[k].set_lane(i, c[k]);
                    }
                }
                let r = offset_ray_origin_lanes(l, v[0], v[1], v[2], v[3]);
                out.extend((0..chunk.len()).map(|i| r.lane(i)));
            }
            out
        }
    }

    /// The lane offset against the scalar offset of before, lane by lane, on every backend
    /// this processor runs (the width-1 one is the scalar engine's).
    #[test]
    fn offset_in_lanes_matches_the_scalar_offset_bit_for_bit() {
        let cases = offset_cases();
        let want: Vec<Vec3> = cases
            .iter()
            .map(|c| offset_reference(c[0], c[1], c[2], c[3]))
            .collect();
        let mut backends = 0;
        for b in crate::simd::Backend::all_supported() {
            backends += 1;
            let got = crate::simd::dispatch(b, OffsetProgram(&cases)).expect("supported");
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(
                    (0..3).all(|i| same(g[i], w[i])),
                    "{b}: case {k} {:?} gave {g:?}, the scalar offset {w:?}",
                    cases[k]
                );
            }
        }
        assert!(backends >= 2);
        // the public scalar function is the width-1 instance
        for c in &cases {
            let (g, w) = (
                offset_ray_origin(c[0], c[1], c[2], c[3]),
                offset_reference(c[0], c[1], c[2], c[3]),
            );
            assert!((0..3).all(|i| same(g[i], w[i])), "{c:?}");
        }
        // the cases reach every branch: moved up, down, and not at all
        let moved = |s: f32| {
            cases
                .iter()
                .zip(&want)
                .filter(|(c, w)| (0..3).any(|i| w[i] != c[0][i] && (w[i] - c[0][i]).signum() == s))
                .count()
        };
        assert!(
            moved(1.0) > 1000 && moved(-1.0) > 1000,
            "{} {}",
            moved(1.0),
            moved(-1.0)
        );
    }

    /// `Frame::from_normal` as it was before the lane kernel (issue 42, step 3b).
    fn from_normal_reference(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// `Frame::from_normal_tangent` as it was before the lane kernel (issue 42, step 3b):
    /// the oracle of [`Frames::from_normal_tangent`].
    fn from_normal_tangent_reference(n: Vec3, dp_du: Vec3) -> Frame {
        let s = dp_du - n * n.dot(dp_du);
        let m = s.abs().max_element();
        if !(m > 0.0 && m.is_finite()) {
            return from_normal_reference(n);
        }
        match (s / m).try_normalize() {
            Some(s) => Frame {
                s,
                t: n.cross(s),
                n,
            },
            None => from_normal_reference(n),
        }
    }

    /// Random (normal, tangent) pairs with the edges of the shading frame: zero, tiny
    /// (1e-30) and huge (1e30) tangents, tangents parallel to the normal, infinite and NaN
    /// components, normals along ±z (the branch point of `from_normal`), ±0.
    fn frame_cases() -> Vec<[Vec3; 2]> {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(0xf4a3e5);
        let unit = |rng: &mut rand_pcg::Pcg32| {
            Vec3::new(
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-1.0f32..1.0),
            )
            .normalize_or_zero()
        };
        let special = [
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(0.0, -0.0, -0.0),
            Vec3::new(-0.0, 0.0, 1.0),
            Vec3::new(1e-8, 0.0, -1.0).normalize(),
            Vec3::X,
        ];
        (0..16 * 2048)
            .map(|_| {
                let n = match rng.random_range(0..4) {
                    0 => special[rng.random_range(0..special.len())],
                    _ => unit(&mut rng),
                };
                let t = unit(&mut rng) * rng.random_range(0.1f32..10.0);
                let dp_du = match rng.random_range(0..12) {
                    0 => Vec3::ZERO,
                    1 => t * 1e-30,
                    2 => t * 1e30,
                    3 => n * rng.random_range(-3.0f32..3.0),
                    4 => Vec3::new(f32::INFINITY, t.y, t.z),
                    5 => Vec3::new(t.x, f32::NAN, t.z),
                    6 => Vec3::new(1e-42, -1e-42, 0.0),
                    7 => n + t * 1e-7,
                    _ => t,
                };
                [n, dp_du]
            })
            .collect()
    }

    struct FrameProgram<'a>(&'a [[Vec3; 2]]);

    impl crate::simd::LaneProgram for FrameProgram<'_> {
        type Output = Vec<[Frame; 2]>;
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Vec<[Frame; 2]> {
            let mut out = Vec::with_capacity(self.0.len());
            for chunk in self.0.chunks(L::WIDTH) {
                let mut v = [V3::splat(l.splat(0.0)); 2];
                for (i, c) in chunk.iter().enumerate() {
                    v[0].set_lane(i, c[0]);
                    v[1].set_lane(i, c[1]);
                }
                let f = Frames::from_normal_tangent(l, v[0], v[1]);
                let g = Frames::from_normal(l, v[0]);
                out.extend((0..chunk.len()).map(|i| [f.lane(i), g.lane(i)]));
            }
            out
        }
    }

    /// The shading frames in lanes against the scalar code of before, lane by lane, on
    /// every backend this processor runs; the public scalar functions are the width-1
    /// instances.
    #[test]
    fn frames_in_lanes_match_the_scalar_code_bit_for_bit() {
        let cases = frame_cases();
        let want: Vec<[Frame; 2]> = cases
            .iter()
            .map(|c| {
                [
                    from_normal_tangent_reference(c[0], c[1]),
                    from_normal_reference(c[0]),
                ]
            })
            .collect();
        let bits = |f: &[Frame; 2]| {
            f.iter()
                .flat_map(|f| [f.s, f.t, f.n])
                .flat_map(|v| v.to_array())
                .map(|x| if x.is_nan() { u32::MAX } else { x.to_bits() })
                .collect::<Vec<u32>>()
        };
        let mut backends = 0;
        for b in crate::simd::Backend::all_supported() {
            backends += 1;
            let got = crate::simd::dispatch(b, FrameProgram(&cases)).expect("supported");
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                assert_eq!(bits(g), bits(w), "{b}: case {k} {:?}", cases[k]);
            }
        }
        assert!(backends >= 2);
        for (c, w) in cases.iter().zip(&want) {
            let g = [
                Frame::from_normal_tangent(c[0], c[1]),
                Frame::from_normal(c[0]),
            ];
            assert_eq!(bits(&g), bits(w), "{c:?}");
        }
        // the cases reach both ways: the tangent followed, and the fallback taken
        let fallback = cases
            .iter()
            .zip(&want)
            .filter(|(c, w)| w[0].s == w[1].s && c[1] != Vec3::ZERO)
            .count();
        let followed = cases
            .iter()
            .zip(&want)
            .filter(|(_, w)| w[0].s != w[1].s && w[0].s.is_finite())
            .count();
        assert!(fallback > 1000 && followed > 10000, "{fallback} {followed}");
    }
}
