//! Three lane values as one vector (structure of arrays), each operation glam's `Vec3`
//! operation in the same order, so that lane i of a result has the bits of the scalar
//! computation on lane i's inputs.

use super::LaneF32;
use glam::Vec3;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// x, y and z lanes.
#[derive(Clone, Copy, Debug)]
pub struct V3<F> {
    pub x: F,
    pub y: F,
    pub z: F,
}

impl<F: LaneF32> V3<F> {
    #[inline(always)]
    pub fn new(x: F, y: F, z: F) -> Self {
        V3 { x, y, z }
    }

    #[inline(always)]
    pub fn splat(v: F) -> Self {
        V3 { x: v, y: v, z: v }
    }

    /// Lane `i` as a glam vector.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec3 {
        Vec3::new(self.x.lane(i), self.y.lane(i), self.z.lane(i))
    }

    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, v: Vec3) {
        self.x.set_lane(i, v.x);
        self.y.set_lane(i, v.y);
        self.z.set_lane(i, v.z);
    }

    /// `if m { a } else { b }` lane by lane.
    #[inline(always)]
    pub fn select(m: F::M, a: Self, b: Self) -> Self {
        V3 {
            x: F::select(m, a.x, b.x),
            y: F::select(m, a.y, b.y),
            z: F::select(m, a.z, b.z),
        }
    }

    /// (x·x′ + y·y′) + z·z′, as glam.
    #[inline(always)]
    pub fn dot(self, o: Self) -> F {
        (self.x * o.x) + (self.y * o.y) + (self.z * o.z)
    }

    /// glam's `cross`.
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        V3 {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    #[inline(always)]
    pub fn length_squared(self) -> F {
        self.dot(self)
    }

    #[inline(always)]
    pub fn length(self) -> F {
        self.dot(self).sqrt()
    }

    /// v · (1 / length), as glam's `normalize`.
    #[inline(always)]
    pub fn normalize(self, one: F) -> Self {
        self * (one / self.length())
    }

    /// glam's `normalize_or_zero`: v · r with r = 1 / length where r is finite and positive,
    /// else zero.
    #[inline(always)]
    pub fn normalize_or_zero(self, one: F, zero: F) -> Self {
        let rcp = one / self.length();
        let ok = rcp.is_finite() & rcp.cmp_gt(zero);
        V3::select(ok, self * rcp, V3::splat(zero))
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        V3 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// glam's `min`: `if a < b { a } else { b }` per component.
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        V3 {
            x: self.x.min_lt(o.x),
            y: self.y.min_lt(o.y),
            z: self.z.min_lt(o.z),
        }
    }

    /// glam's `max`.
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        V3 {
            x: self.x.max_gt(o.x),
            y: self.y.max_gt(o.y),
            z: self.z.max_gt(o.z),
        }
    }

    /// glam's `max_element`: max(x, max(y, z)) with `if a > b { a } else { b }`.
    #[inline(always)]
    pub fn max_element(self) -> F {
        self.x.max_gt(self.y.max_gt(self.z))
    }

    /// glam's `min_element`.
    #[inline(always)]
    pub fn min_element(self) -> F {
        self.x.min_lt(self.y.min_lt(self.z))
    }

    /// glam's `Vec3 == Vec3` (every component equal).
    #[inline(always)]
    pub fn cmp_eq(self, o: Self) -> F::M {
        self.x.cmp_eq(o.x) & self.y.cmp_eq(o.y) & self.z.cmp_eq(o.z)
    }

    /// glam's `is_finite` (every component finite).
    #[inline(always)]
    pub fn is_finite(self) -> F::M {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }
}

/// The width-1 instance is glam's vector, component by component.
impl From<Vec3> for V3<f32> {
    #[inline(always)]
    fn from(v: Vec3) -> Self {
        V3::new(v.x, v.y, v.z)
    }
}

impl From<V3<f32>> for Vec3 {
    #[inline(always)]
    fn from(v: V3<f32>) -> Self {
        Vec3::new(v.x, v.y, v.z)
    }
}

impl<F: LaneF32> Add for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        V3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl<F: LaneF32> Sub for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        V3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

/// Component by component (a spectrum times a spectrum).
impl<F: LaneF32> Mul for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        V3::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }
}

impl<F: LaneF32> Div for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        V3::new(self.x / o.x, self.y / o.y, self.z / o.z)
    }
}

/// Times one lane value per lane (glam's `Vec3 * f32`).
impl<F: LaneF32> Mul<F> for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: F) -> Self {
        V3::new(self.x * s, self.y * s, self.z * s)
    }
}

/// Divided by one lane value per lane (glam's `Vec3 / f32`: each component divided).
impl<F: LaneF32> Div<F> for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn div(self, s: F) -> Self {
        V3::new(self.x / s, self.y / s, self.z / s)
    }
}

impl<F: LaneF32> Neg for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        V3::new(-self.x, -self.y, -self.z)
    }
}
