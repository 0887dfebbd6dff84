//! Mitsuba 3's own render regression suite (`validation/mitsuba-suite/`), judged by Mitsuba's
//! own acceptance rule (`penumbra::study::suite`): spp = 2e6 / pixels, seed 0, per-pixel
//! z-test in XYZ against the reference's variance, Šidák α = 0.01, at least 99.75% of the
//! pixel-channels passing.
//!
//! Every scene of the suite is run and reported (pass, fail, or the first unsupported
//! construct, printed with `--nocapture`), and every scene must pass: the 12 participating
//! media scenes (volpath, volpathmis) and the particle tracer's (`ptracer`) included.

use penumbra::study::suite::{self, Outcome};
use std::path::Path;

#[test]
fn mitsuba_regression_suite() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/mitsuba-suite");
    let scenes = suite::discover(&root).expect("the suite is in the repository");
    assert_eq!(scenes.len(), 41, "Mitsuba's suite has 41 scenes");
    let ptracer = scenes
        .iter()
        .filter(|s| s.name.ends_with("_ptracer"))
        .count();
    assert_eq!(ptracer, 1, "the suite has one particle-tracer scene");
    let media = scenes
        .iter()
        .filter(|s| s.name.starts_with("participating_media/"))
        .count();
    assert_eq!(media, 12, "the suite has 12 participating-media scenes");
    let mut failures = Vec::new();
    for s in &scenes {
        match suite::run(s, None) {
            Outcome::Judged(j) => {
                println!(
                    "{:<62} {}  {} spp  {:.2} s",
                    s.name,
                    j.summary(),
                    j.spp,
                    j.seconds
                );
                if !j.passed {
                    failures.push(format!(
                        "{} fails Mitsuba's test: {:.2}% of pixel-channels pass",
                        s.name,
                        100.0 * j.pass_fraction
                    ));
                }
            }
            Outcome::Unsupported(e) => {
                println!("{:<62} unsupported: {e}", s.name);
                failures.push(format!("{} does not load: {e}", s.name));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
