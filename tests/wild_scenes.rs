//! Published Mitsuba 3 scenes that nobody on this project wrote (scenes/wild/, listed in its
//! manifest.json with their reduced-resolution defines): every one loads unchanged, builds,
//! and renders finite samples. How they agree with Mitsuba is the validation study's
//! (validation/scenes.toml, the `wild-*` entries).

mod common;
use common::{render_scene, repo_path};
use penumbra::render::Job;

#[test]
fn every_wild_scene_loads_unchanged_and_renders() {
    let manifest: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo_path("scenes/wild/manifest.json")).unwrap(),
    )
    .unwrap();
    let entries = manifest.as_array().unwrap();
    assert_eq!(entries.len(), 6, "the six scenes of the manifest");
    let mut failures = Vec::new();
    for e in entries {
        let name = e["name"].as_str().unwrap();
        // Defines as the manifest gives them, but 16 pixels wide (same aspect).
        let (w, h) = (
            e["defines"]["resx"]
                .as_str()
                .unwrap()
                .parse::<f64>()
                .unwrap(),
            e["defines"]["resy"]
                .as_str()
                .unwrap()
                .parse::<f64>()
                .unwrap(),
        );
        let mut defines: Vec<(String, String)> = e["defines"]
            .as_object()
            .unwrap()
            .iter()
            .map(|(k, v)| (k.clone(), v.as_str().unwrap().to_string()))
            .collect();
        for (k, v) in defines.iter_mut() {
            match k.as_str() {
                "resx" => *v = "16".into(),
                "resy" => *v = format!("{}", (16.0 * h / w).round()),
                _ => {}
            }
        }
        let path = repo_path(&format!("scenes/wild/{}", e["scene"].as_str().unwrap()));
        match Job::load(&path, &defines) {
            Err(err) => failures.push(format!("{name}: {err}")),
            Ok(scene) => {
                assert_eq!(scene.scene.width, 16, "{name}");
                let out = render_scene(&scene, 2, 1, None);
                assert_eq!(out.stats.nonfinite, 0, "{name}");
                let img = out.film.image();
                assert!(
                    img.iter().flatten().all(|v| v.is_finite() && *v >= 0.0),
                    "{name}"
                );
                // every scene is lit: some pixel is not black
                assert!(
                    img.iter().flatten().any(|v| *v > 0.0),
                    "{name}: black image"
                );
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
