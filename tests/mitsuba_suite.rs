//! Mitsuba 3's own render regression suite (`validation/mitsuba-suite/`), judged by Mitsuba's
//! own acceptance rule (`penumbra::study::suite`): spp = 2e6 / pixels, seed 0, per-pixel
//! z-test in XYZ against the reference's variance, Šidák α = 0.01, at least 99.75% of the
//! pixel-channels passing.
//!
//! Every scene of the suite is run and reported (pass, fail, or the first unsupported
//! construct, printed with `--nocapture`). The scenes penumbra passes are listed in [`PASSING`]
//! and asserted to pass, so nothing regresses; a scene that cannot be loaded must fail with a
//! single line naming what penumbra does not support.

use penumbra::study::suite::{self, Outcome};
use std::path::Path;

/// Scenes that pass Mitsuba's test today.
const PASSING: &[&str] = &[
    "bsdf_spheres/test_roughdielectric_path",
    "bsdf_spheres/test_roughplastic_linear_path",
    "bsdf_spheres/test_roughplastic_nonlinear_path",
    "floating_sphere/test_directional_direct",
    "infinite_mirrors/scene_path",
    "instancing/test_instancing_path",
];

#[test]
fn mitsuba_regression_suite() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/mitsuba-suite");
    let scenes = suite::discover(&root).expect("the suite is in the repository");
    assert_eq!(scenes.len(), 41, "Mitsuba's suite has 41 scenes");
    for name in PASSING {
        assert!(
            scenes.iter().any(|s| s.name == *name),
            "{name} is not a scene of the suite"
        );
    }
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
                if PASSING.contains(&s.name.as_str()) && !j.passed {
                    failures.push(format!(
                        "{} fails Mitsuba's test: {:.2}% of pixel-channels pass",
                        s.name,
                        100.0 * j.pass_fraction
                    ));
                }
            }
            Outcome::Unsupported(e) => {
                println!("{:<62} unsupported: {e}", s.name);
                if PASSING.contains(&s.name.as_str()) {
                    failures.push(format!("{} no longer loads: {e}", s.name));
                }
                if e.contains('\n') || e.is_empty() {
                    failures.push(format!("{}: the error is not one line: {e:?}", s.name));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
