//! `penumbra merge`: the part files of a split render merged into its image.

use super::output::{check_outputs, write_image, ImageOutput};
use anyhow::Result;
use penumbra::progressive;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub(crate) struct MergeArgs {
    /// Part files written by `penumbra render --part I/N`, in any order.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output image (OpenEXR, 32-bit float linear RGB).
    #[arg(short, long, default_value = "out.exr")]
    output: PathBuf,
    /// Merge only the samples up to this spp (a rung of a convergence ladder): parts beyond
    /// it are left out. Default: everything the parts hold.
    #[arg(long)]
    spp: Option<u64>,
    /// Add per-pixel per-sample variance channels (variance.R/G/B) to the EXR.
    #[arg(long)]
    variance: bool,
    /// Also write a tone-mapped sRGB PNG preview.
    #[arg(long, value_name = "PNG")]
    preview: Option<PathBuf>,
    /// Write render statistics (summed over the parts) as JSON.
    #[arg(long, value_name = "JSON")]
    stats: Option<PathBuf>,
    /// No summary line.
    #[arg(short, long)]
    quiet: bool,
}

pub(crate) fn run_merge(args: MergeArgs) -> Result<()> {
    let mut outputs: Vec<(&Path, &str)> = vec![(&args.output, "image")];
    if let Some(p) = &args.preview {
        outputs.push((p, "preview"));
    }
    if let Some(p) = &args.stats {
        outputs.push((p, "statistics"));
    }
    check_outputs(&outputs)?;
    // One part in memory at a time: the merge's memory does not grow with the parts.
    let merged = progressive::merge_part_files(&args.parts, args.spp)?;
    write_image(&ImageOutput {
        output: &args.output,
        film: &merged.film(),
        spp: merged.samples,
        seed: merged.seed,
        stats: merged.stats,
        reason: "merged parts",
        variance: args.variance,
        preview: args.preview.as_deref(),
        stats_json_path: args.stats.as_deref(),
        quiet: args.quiet,
    })
}
