//! Fuzzes the whole scene input path: XML parsing (includes, defaults, refs, transforms),
//! the typed description, the scene build (meshes, BVH) and, for small films, a 1-spp render.
//! Any panic, hang or unbounded allocation is a bug: every input must end in Ok or Err.
#![no_main]

use libfuzzer_sys::fuzz_target;
use penumbra::render::{Job, RenderSettings};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(job) = Job::from_xml_str(text, Path::new("fuzz/scene.xml"), &[])
    else {
        return;
    };
    if job.scene.width * job.scene.height <= 256 {
        let settings = RenderSettings {
            spp: 1,
            seed: 0,
            threads: Some(1),
            first_sample: 0,
            sampler: None,
        };
        let _ = job.render(&settings, &|_, _| {});
    }
});
