//! Fuzzes the `.vol` grid reader and, for one-channel grids, the `sdfgrid` shape built from
//! it: construction (sign tests, the chessboard distance transform), a few rays through
//! the DDA and the per-voxel cubic, and the surface interaction at their hits.
#![no_main]

use glam::{DMat4, DVec3, Vec3};
use libfuzzer_sys::fuzz_target;
use penumbra::geometry::Ray;
use penumbra::io::vol::parse_vol;
use penumbra::shape::sdfgrid::{SdfGrid, SdfNormals};

fuzz_target!(|data: &[u8]| {
    let Ok(vol) = parse_vol(data) else {
        return;
    };
    assert_eq!(
        vol.data.len(),
        vol.res[0] * vol.res[1] * vol.res[2] * vol.channels
    );
    let to_world = DMat4::from_translation(DVec3::new(-0.5, 0.25, 1.0))
        * DMat4::from_scale(DVec3::new(2.0, 1.0, 0.5));
    let Ok(grid) = SdfGrid::new(vol, to_world, SdfNormals::Smooth, false) else {
        return;
    };
    let [lo, hi] = grid.bounds();
    let centre = (lo + hi) * 0.5;
    for d in [
        Vec3::X,
        -Vec3::Y,
        Vec3::Z,
        Vec3::new(0.3, -0.5, 0.8).normalize(),
        Vec3::new(-0.7, 0.1, -0.2),
    ] {
        for o in [centre - d * 10.0, centre, lo] {
            let ray = Ray::new(o, d, f32::INFINITY);
            if let Some(t) = grid.intersect(&ray) {
                assert!(t > 0.0);
                let _ = grid.interaction(&ray, t, 0);
            }
        }
    }
});
