//! Fuzzes the OBJ mesh path: tobj parsing, validation of faces (non-finite and degenerate
//! faces skipped), vertex normals, the BVH build and a few rays through the result.
#![no_main]

use glam::{DMat4, Vec3};
use libfuzzer_sys::fuzz_target;
use penumbra::accel::Accel;
use penumbra::geometry::Ray;
use penumbra::scene::build::obj_from_bytes;
use penumbra::shape::{Shape, ShapeGeometry};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let mut warnings = Vec::new();
    let Ok(mesh) = obj_from_bytes(
        data,
        Path::new("fuzz.obj"),
        DMat4::IDENTITY,
        false,
        true,
        false,
        &mut warnings,
    ) else {
        return;
    };
    let shapes = vec![Shape {
        geometry: ShapeGeometry::Mesh(mesh),
        bsdf: 0,
        emitter: None,
    }];
    let accel = Accel::build(&shapes);
    for d in [
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::new(0.3, -0.5, 0.8).normalize(),
    ] {
        let ray = Ray::new(Vec3::splat(0.1), d, f32::INFINITY);
        if let Some(hit) = accel.intersect(&ray, &shapes) {
            let _ = accel.interaction(&hit, &ray, &shapes);
        }
        let _ = accel.occluded(&ray, &shapes);
    }
});
