//! `penumbra compare`: an image against a reference (metrics, z-test, false-colour diff).

use super::file_name;
use anyhow::{bail, Result};
use penumbra::io::exr;
use penumbra::study::compare;
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct CompareArgs {
    /// The image to measure (OpenEXR).
    a: PathBuf,
    /// The reference (OpenEXR), e.g. a Mitsuba reference from validation/references/.
    b: PathBuf,
    /// Write a signed false-colour difference image (A − B) with a colour bar, as PNG.
    #[arg(long, value_name = "PNG")]
    diff: Option<PathBuf>,
    /// Half-range of the diff's colour map (default: the 99th percentile of |A − B|).
    #[arg(long, value_name = "R", requires = "diff")]
    diff_range: Option<f64>,
    /// Print the results as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Samples per pixel of A for the z-test (default: its `spp` header attribute).
    #[arg(long, value_name = "N")]
    spp_a: Option<f64>,
    /// Samples per pixel of B for the z-test (default: its `spp` header attribute).
    #[arg(long, value_name = "N")]
    spp_b: Option<f64>,
}

pub(crate) fn run_compare(args: CompareArgs) -> Result<()> {
    for (flag, v) in [("--spp-a", args.spp_a), ("--spp-b", args.spp_b)] {
        if let Some(v) = v {
            if !(v > 0.0 && v.is_finite()) {
                bail!("{flag} must be a positive number, got {v}");
            }
        }
    }
    if let Some(r) = args.diff_range {
        if !(r > 0.0 && r.is_finite()) {
            bail!("--diff-range must be a positive number, got {r}");
        }
    }
    let a = exr::read(&args.a)?;
    let b = exr::read(&args.b)?;
    let alpha = penumbra::study::validation::ALPHA;
    let cmp = compare::compare(&a, &b, args.spp_a, args.spp_b, alpha)?;
    let diff_path = args.diff.as_ref().map(|p| p.to_string_lossy().into_owned());
    let mut diff_range = None;
    if let Some(path) = &args.diff {
        let values = compare::signed_difference(&a.rgb, &b.rgb);
        let (range, note) = match args.diff_range {
            Some(r) => (r, "set by --diff-range".to_string()),
            None => (
                compare::default_diff_range(&values),
                "99th percentile of |Δ|".to_string(),
            ),
        };
        let title = format!("A − B: {} − {}", file_name(&args.a), file_name(&args.b));
        penumbra::study::plot::write_diff_png(
            path,
            &penumbra::study::plot::DiffImage {
                width: a.width,
                height: a.height,
                values: &values,
                range,
                range_note: &note,
                title: &title,
            },
        )?;
        diff_range = Some(range);
    }
    let (a_name, b_name) = (args.a.to_string_lossy(), args.b.to_string_lossy());
    if args.json {
        let diff = diff_path
            .as_deref()
            .zip(diff_range)
            .map(|(path, range)| compare::DiffJson { path, range });
        let json = cmp.to_json(&a_name, &b_name, alpha, diff);
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        print!("{}", cmp.text(&a_name, &b_name));
        if let (Some(p), Some(r)) = (&diff_path, diff_range) {
            println!("diff image: {p} (colour range ±{r:.4e})");
        }
    }
    Ok(())
}
