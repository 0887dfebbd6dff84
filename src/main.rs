//! The `penumbra` command line.
//!
//! `main` and the subcommand enum are here; each subcommand's arguments and its run
//! function are in `cli` (see its module doc).

mod cli;

use clap::{Parser, Subcommand};
use cli::compare::{run_compare, CompareArgs};
use cli::converge::{run_converge, ConvergeArgs};
use cli::merge::{run_merge, MergeArgs};
use cli::render::{run_render, Interrupted, RenderArgs};
use cli::report::{run_report, ReportArgs};

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "A physically based path tracer for Mitsuba 3 scenes",
    after_help = "Environment: PENUMBRA_LIMITS=name=value,... raises (or lowers) the limits on \
                  input a large scene may exceed: render_pixels, image_pixels, image_bytes, \
                  mesh_bytes, shape_bytes, vol_bytes, radiosity_rays (e.g. \
                  PENUMBRA_LIMITS=render_pixels=2^28,mesh_bytes=32G; see docs/usage.md, Limits)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a Mitsuba 3 XML scene to an OpenEXR image.
    Render(RenderArgs),
    /// Merge the part files of a render split with `render --part i/N` into its image,
    /// bit-identical to the render made in one process.
    Merge(MergeArgs),
    /// Compare image A with the reference B: error metrics, z-test, false-colour diff.
    Compare(CompareArgs),
    /// Render a ladder of sample counts against a reference: error vs. spp and time, slope,
    /// efficiency; optionally over several seeds and a swept scene parameter.
    Converge(ConvergeArgs),
    /// Write an interactive HTML page comparing images with a reference: flip, zoom to
    /// single pixels, change exposure, error maps, metrics, convergence plots. A static
    /// folder that opens from disk.
    Report(ReportArgs),
    /// Print the BSDF plugins' parameter tables (name, kind, default, range) as Markdown.
    Plugins,
}

fn main() {
    let cli = Cli::parse();
    // PENUMBRA_LIMITS is read once, here, before anything is loaded: a malformed value fails
    // at once with one line (the loaders then use the same value).
    let result = match penumbra::limits::current() {
        Err(e) => Err(e.into()),
        Ok(_) => match cli.command {
            Command::Render(args) => run_render(args),
            Command::Merge(args) => run_merge(args),
            Command::Compare(args) => run_compare(args),
            Command::Converge(args) => run_converge(args),
            Command::Report(args) => run_report(args),
            Command::Plugins => {
                print!("{}", penumbra::bsdf::plugin::markdown());
                Ok(())
            }
        },
    };
    if let Err(e) = result {
        if let Some(i) = e.downcast_ref::<Interrupted>() {
            eprintln!("{i}");
            std::process::exit(128 + i.signal);
        }
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
