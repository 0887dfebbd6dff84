//! Runs Mitsuba's render regression suite (`validation/mitsuba-suite/`) as Mitsuba's own test
//! does (see `penumbra::study::suite`) and prints one markdown row per scene: passed, failed
//! (with the share of passing pixel-channels and the mean difference), or the first construct
//! penumbra does not support.
//!
//!     cargo run --release --bin suite [-- --scene SUBSTRING] [--threads N] [--mode spectral]

use clap::Parser;
use penumbra::study::suite::{self, Outcome};
use std::path::PathBuf;

#[derive(Parser)]
struct Args {
    /// Root of the suite.
    #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/validation/mitsuba-suite"))]
    root: PathBuf,
    /// Only scenes whose name contains this.
    #[arg(long)]
    scene: Option<String>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Render every scene with this integrator instead of its own (as `render --integrator`
    /// switches it: max_depth, rr_depth and hide_emitters kept), against the same reference;
    /// a scene it cannot render (media for `bdpt`) is reported unsupported.
    #[arg(long)]
    integrator: Option<String>,
    /// `spectral`: render in spectral mode (as `render --mode spectral`) and judge against
    /// Mitsuba's spectral references (`_ref_spectral.exr`).
    #[arg(long, default_value = "rgb")]
    mode: String,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let mut scenes = suite::discover(&args.root)?;
    match args.mode.as_str() {
        "rgb" => {}
        "spectral" => scenes = scenes.into_iter().map(|s| s.spectral()).collect(),
        m => anyhow::bail!("--mode must be rgb or spectral, not {m}"),
    }
    println!("| scene | result, pixel-channels passing | mean diff R / G / B | spp | time (s) |");
    println!("|---|---|---|---:|---:|");
    let (mut passed, mut failed, mut unsupported) = (0, 0, 0);
    for s in scenes.iter().filter(|s| {
        args.scene
            .as_ref()
            .is_none_or(|f| s.name.contains(f.as_str()))
    }) {
        let outcome = match &args.integrator {
            None => suite::run(s, args.threads),
            Some(kind) => {
                let mut why = String::new();
                suite::run_with(s, args.threads, &mut |job| match switch(
                    &s.path,
                    &s.integrator,
                    kind,
                    &job.scene,
                ) {
                    Ok(i) => {
                        job.integrator = i;
                        true
                    }
                    Err(e) => {
                        why = e.to_string();
                        false
                    }
                })
                .unwrap_or_else(|| Outcome::Unsupported(why.clone()))
            }
        };
        match outcome {
            Outcome::Judged(j) => {
                if j.passed {
                    passed += 1;
                } else {
                    failed += 1;
                }
                println!(
                    "| {} | {} | {} | {:.2} |",
                    s.name,
                    j.summary(),
                    j.spp,
                    j.seconds
                );
            }
            Outcome::Unsupported(e) => {
                unsupported += 1;
                // The scene path is long and the same for every line of a group: drop it.
                let short = e
                    .rsplit_once(".xml:")
                    .map(|(_, rest)| format!("line {rest}"))
                    .unwrap_or(e);
                println!(
                    "| {} | unsupported | {} | | |",
                    s.name,
                    short.replace('|', "\\|")
                );
            }
        }
    }
    println!("\n{passed} passed, {failed} failed, {unsupported} not loadable");
    Ok(())
}

/// The integrator of the scene at `path` (its `$integrator` set to `own`) switched to `kind`.
fn switch(
    path: &std::path::Path,
    own: &str,
    kind: &str,
    scene: &penumbra::scene::Scene,
) -> penumbra::error::Result<penumbra::integrator::Integrator> {
    let defines = [("integrator".to_string(), own.to_string())];
    let desc = penumbra::scene::Scene::load_description(path, &defines)?;
    let switched = desc.integrator.switched_to(kind)?;
    penumbra::integrator::Integrator::build(&switched, scene)
}
