//! Volumes: spatially varying quantities of a medium (Mitsuba's `volume` plugins), looked up
//! at world-space points. One file per plugin; this enum dispatches.
//!
//! | plugin | file | what it holds |
//! |---|---|---|
//! | `constvolume` | [`constant`] | one value everywhere |
//! | `gridvolume` | [`grid`] | a `.vol` grid, trilinear or nearest lookups |
//!
//! Every volume has Mitsuba's bounding box: its `to_world` applied to the unit cube (for a grid
//! with `use_grid_bbox`, the file's box). A heterogeneous medium samples interactions only
//! inside the box of its `sigma_t`, as Mitsuba's does; a plain `<rgb>`/`<float>` parameter
//! is a constant volume with the identity `to_world`, so its box is [0, 1]³.

pub mod constant;
pub mod grid;

pub use grid::GridVolume;

use glam::{Mat4, Vec3};

#[derive(Clone, Debug)]
pub enum Volume {
    Constant(constant::ConstVolume),
    Grid(Box<GridVolume>),
}

impl Volume {
    /// A constant volume with the identity `to_world` (a plain parameter value).
    pub fn constant(value: Vec3) -> Self {
        Volume::Constant(constant::ConstVolume::new(value, Mat4::IDENTITY))
    }

    /// The value at world-space point `p` (one-channel grids are splatted to RGB).
    #[inline]
    pub fn eval(&self, p: Vec3) -> Vec3 {
        match self {
            Volume::Constant(c) => c.value,
            Volume::Grid(g) => g.eval(p),
        }
    }

    /// The largest value of any channel anywhere (Mitsuba's `Volume::max`), the majorant of a
    /// heterogeneous medium.
    pub fn max(&self) -> f32 {
        match self {
            Volume::Constant(c) => c.value.max_element(),
            Volume::Grid(g) => g.max,
        }
    }

    /// World-space bounding box `[min, max]`.
    pub fn bbox(&self) -> [Vec3; 2] {
        match self {
            Volume::Constant(c) => c.bbox,
            Volume::Grid(g) => g.bbox,
        }
    }
}

/// The world-space box of the unit cube under `to_world` (Mitsuba's `Volume::update_bbox`).
pub fn unit_cube_bbox(to_world: &Mat4) -> [Vec3; 2] {
    let mut lo = Vec3::INFINITY;
    let mut hi = Vec3::NEG_INFINITY;
    for i in 0..8 {
        let c = Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32);
        let p = to_world.transform_point3(c);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    [lo, hi]
}
