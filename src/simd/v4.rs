//! Four lane values as one vector (structure of arrays): a spectrum over lanes, as
//! [`crate::spectrum::Spectrum`] is glam's `Vec4` (RGB mode's (R, G, B, G), or the values at
//! four wavelengths in spectral mode). Each operation is glam's `Vec4` operation component by
//! component, so that lane i of a result has the bits of the scalar computation on lane i's
//! inputs.

use super::LaneF32;
use glam::Vec4;
use std::ops::{Add, Div, Mul, Sub};

/// x, y, z and w lanes.
#[derive(Clone, Copy, Debug)]
pub struct V4<F> {
    pub x: F,
    pub y: F,
    pub z: F,
    pub w: F,
}

impl<F: LaneF32> V4<F> {
    #[inline(always)]
    pub fn new(x: F, y: F, z: F, w: F) -> Self {
        V4 { x, y, z, w }
    }

    #[inline(always)]
    pub fn splat(v: F) -> Self {
        V4::new(v, v, v, v)
    }

    /// Lane `i` as a glam vector.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec4 {
        Vec4::new(
            self.x.lane(i),
            self.y.lane(i),
            self.z.lane(i),
            self.w.lane(i),
        )
    }

    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, v: Vec4) {
        self.x.set_lane(i, v.x);
        self.y.set_lane(i, v.y);
        self.z.set_lane(i, v.z);
        self.w.set_lane(i, v.w);
    }

    /// `if m { a } else { b }` lane by lane.
    #[inline(always)]
    pub fn select(m: F::M, a: Self, b: Self) -> Self {
        V4 {
            x: F::select(m, a.x, b.x),
            y: F::select(m, a.y, b.y),
            z: F::select(m, a.z, b.z),
            w: F::select(m, a.w, b.w),
        }
    }

    /// The largest component, `w.max_gt(x.max_gt(y.max_gt(z)))` with `if a > b { a } else
    /// { b }`: in RGB mode (w = y) bit for bit the three-component maximum, NaN included
    /// (a NaN maximum of x, y, z stays NaN).
    #[inline(always)]
    pub fn max_element(self) -> F {
        self.w.max_gt(self.x.max_gt(self.y.max_gt(self.z)))
    }

    /// Every component equal.
    #[inline(always)]
    pub fn cmp_eq(self, o: Self) -> F::M {
        self.x.cmp_eq(o.x) & self.y.cmp_eq(o.y) & self.z.cmp_eq(o.z) & self.w.cmp_eq(o.w)
    }

    /// Every component finite.
    #[inline(always)]
    pub fn is_finite(self) -> F::M {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite() & self.w.is_finite()
    }
}

/// The width-1 instance is glam's vector, component by component.
impl From<Vec4> for V4<f32> {
    #[inline(always)]
    fn from(v: Vec4) -> Self {
        V4::new(v.x, v.y, v.z, v.w)
    }
}

impl From<V4<f32>> for Vec4 {
    #[inline(always)]
    fn from(v: V4<f32>) -> Self {
        Vec4::new(v.x, v.y, v.z, v.w)
    }
}

impl<F: LaneF32> Add for V4<F> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        V4::new(self.x + o.x, self.y + o.y, self.z + o.z, self.w + o.w)
    }
}

impl<F: LaneF32> Sub for V4<F> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        V4::new(self.x - o.x, self.y - o.y, self.z - o.z, self.w - o.w)
    }
}

/// Component by component (a spectrum times a spectrum).
impl<F: LaneF32> Mul for V4<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        V4::new(self.x * o.x, self.y * o.y, self.z * o.z, self.w * o.w)
    }
}

impl<F: LaneF32> Div for V4<F> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        V4::new(self.x / o.x, self.y / o.y, self.z / o.z, self.w / o.w)
    }
}

/// Times one lane value per lane (glam's `Vec4 * f32`).
impl<F: LaneF32> Mul<F> for V4<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: F) -> Self {
        V4::new(self.x * s, self.y * s, self.z * s, self.w * s)
    }
}

/// Divided by one lane value per lane (glam's `Vec4 / f32`: each component divided).
impl<F: LaneF32> Div<F> for V4<F> {
    type Output = Self;
    #[inline(always)]
    fn div(self, s: F) -> Self {
        V4::new(self.x / s, self.y / s, self.z / s, self.w / s)
    }
}
