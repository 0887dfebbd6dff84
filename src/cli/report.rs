//! `penumbra report`: the interactive HTML page comparing images with a reference.

use anyhow::{bail, Result};
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct ReportArgs {
    /// The reference image (OpenEXR).
    #[arg(long, value_name = "EXR")]
    reference: PathBuf,
    /// The images to compare with it (OpenEXR, the reference's size); keys 2..9 show them.
    #[arg(required = true, value_name = "EXR")]
    images: Vec<PathBuf>,
    /// The folder to write (index.html, data.js, plots/).
    #[arg(short, long, default_value = "report")]
    output: PathBuf,
    /// The page's title (default: the reference's file name).
    #[arg(long)]
    title: Option<String>,
    /// Show a plot under the images: a PNG, or the output folder of `penumbra converge`
    /// (its converge.png). Repeatable.
    #[arg(long, value_name = "PNG|DIR")]
    plot: Vec<PathBuf>,
}

pub(crate) fn run_report(args: ReportArgs) -> Result<()> {
    use penumbra::study::report::{self, ReportImage, ReportPlot, ReportScene};
    let reference = ReportImage::from_file(&args.reference)?;
    let mut images = Vec::with_capacity(args.images.len());
    for path in &args.images {
        images.push(ReportImage::from_file(path)?);
    }
    let mut plots = Vec::new();
    for p in &args.plot {
        let path = if p.is_dir() {
            p.join("converge.png")
        } else {
            p.clone()
        };
        if !path.is_file() {
            bail!(
                "{}: no such plot (give a PNG or a `penumbra converge` output folder)",
                path.display()
            );
        }
        plots.push(ReportPlot {
            caption: path.display().to_string(),
            path,
        });
    }
    let title = args
        .title
        .unwrap_or_else(|| format!("penumbra report: {}", reference.name));
    let scene = ReportScene {
        name: reference.name.clone(),
        reference,
        images,
        plots,
        notes: Vec::new(),
    };
    let summary = report::write_report(&args.output, &title, &[scene])?;
    eprintln!(
        "wrote {} ({:.1} MB): open it in a browser",
        summary.index.display(),
        summary.bytes as f64 / 1e6
    );
    Ok(())
}
