//! Runs Mitsuba's render regression suite (`validation/mitsuba-suite/`) as Mitsuba's own test
//! does (see `penumbra::study::suite`) and prints one markdown row per scene: passed, failed
//! (with the share of passing pixel-channels and the mean difference), or the first construct
//! penumbra does not support.
//!
//!     cargo run --release --bin suite [-- --scene SUBSTRING] [--threads N]

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
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let scenes = suite::discover(&args.root)?;
    println!("| scene | result, pixel-channels passing | mean diff R / G / B | spp | time (s) |");
    println!("|---|---|---|---:|---:|");
    let (mut passed, mut failed, mut unsupported) = (0, 0, 0);
    for s in scenes.iter().filter(|s| {
        args.scene
            .as_ref()
            .is_none_or(|f| s.name.contains(f.as_str()))
    }) {
        match suite::run(s, args.threads) {
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
