//! Mitsuba's `constvolume`: one value everywhere (inside and outside its box).
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `value` | rgb or float | 1 |
//! | `to_world` | transform (sets only the bounding box) | identity |
//!
//! ```xml
//! <volume type="constvolume" name="sigma_t"> <rgb name="value" value="0.5, 0.4, 0.3"/> </volume>
//! ```

use glam::{Mat4, Vec3};

#[derive(Clone, Debug)]
pub struct ConstVolume {
    pub value: Vec3,
    pub bbox: [Vec3; 2],
}

impl ConstVolume {
    pub fn new(value: Vec3, to_world: Mat4) -> Self {
        ConstVolume {
            value,
            bbox: super::unit_cube_bbox(&to_world),
        }
    }
}
