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

use crate::spectrum::{from_rgb, Spectrum};
use crate::texture::ColorValue;
use glam::{Mat4, Vec3, Vec4};

#[derive(Clone, Debug)]
pub enum Volume {
    Constant(constant::ConstVolume),
    Grid(Box<GridVolume>),
}

impl Volume {
    /// A constant RGB volume with the identity `to_world` (a plain parameter value).
    pub fn constant(value: Vec3) -> Self {
        Volume::Constant(constant::ConstVolume::new(
            ColorValue::Rgb(from_rgb(value)),
            Mat4::IDENTITY,
        ))
    }

    /// The value at world-space point `p` and the path's `wavelengths` (ignored in RGB mode):
    /// one-channel grids are the same in every lane, three-channel grids hold RGB in RGB
    /// mode and spectra in spectral mode ([`GridVolume::to_spectral`]).
    #[inline]
    pub fn eval(&self, p: Vec3, wavelengths: Vec4) -> Spectrum {
        match self {
            Volume::Constant(c) => c.value.eval(wavelengths),
            Volume::Grid(g) if g.is_spectral() => g.eval_spectral(p, wavelengths),
            Volume::Grid(g) => from_rgb(g.eval(p)),
        }
    }

    /// The RGB value at `p` of a volume built for RGB mode (volume textures).
    #[inline]
    pub fn eval_rgb(&self, p: Vec3) -> Vec3 {
        crate::spectrum::to_rgb(self.eval(p, crate::spectrum::NO_WAVELENGTHS))
    }

    /// The largest value of any channel anywhere (Mitsuba's `Volume::max`), the majorant of a
    /// heterogeneous medium.
    pub fn max(&self) -> f32 {
        match self {
            Volume::Constant(c) => c.max,
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
