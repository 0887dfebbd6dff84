//! Fuzzes the PLY reader: any input must give Ok or Err (never a panic, a hang or a huge
//! allocation), and an accepted mesh must satisfy `MeshData::validate` (indices in range,
//! array lengths matching).
#![no_main]

use libfuzzer_sys::fuzz_target;
use penumbra::io::ply::read_ply_with_warnings;

fuzz_target!(|data: &[u8]| {
    let mut warnings = Vec::new();
    if let Ok(mesh) = read_ply_with_warnings(data, &mut warnings) {
        mesh.validate()
            .expect("the reader returned an invalid mesh");
        assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()));
    }
});
