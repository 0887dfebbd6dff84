//! Fuzzes the `.serialized` reader: the first byte picks the shape index, the rest is the
//! file. Any input must give Ok or Err, never a panic, and an accepted mesh must satisfy
//! `MeshData::validate`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use penumbra::io::serialized::{read_serialized_shape, serialized_shape_count};

fuzz_target!(|data: &[u8]| {
    let Some((&index, file)) = data.split_first() else {
        return;
    };
    let _ = serialized_shape_count(file);
    if let Ok(shape) = read_serialized_shape(file, usize::from(index % 4)) {
        shape
            .mesh
            .validate()
            .expect("the reader returned an invalid mesh");
    }
});
