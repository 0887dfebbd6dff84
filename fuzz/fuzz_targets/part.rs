//! Fuzzes the checkpoint / part file reader and the merge: arbitrary bytes, with a valid
//! checksum appended so that the parser's structure is reached, must parse or be refused with
//! an error, never panic; a file that parses is merged with itself (refused as a duplicate or
//! as a checkpoint) and alone, and its film is converted.
#![no_main]

use libfuzzer_sys::fuzz_target;
use penumbra::progressive::{fnv1a, merge_parts, Checkpoint};
use std::path::{Path, PathBuf};

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    bytes.extend_from_slice(&fnv1a(data, 0xcbf2_9ce4_8422_2325).to_le_bytes());
    let Ok(c) = Checkpoint::parse(&bytes, Path::new("fuzz.pnbr")) else {
        return;
    };
    let _ = c.film();
    let p = PathBuf::from("a.pnbr");
    let _ = merge_parts(vec![(p.clone(), c.clone())], None);
    let _ = merge_parts(vec![(p.clone(), c.clone()), (p, c)], Some(7));
});
