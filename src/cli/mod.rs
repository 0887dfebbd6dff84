//! The subcommands of the `penumbra` binary (not part of the library), one module each, with
//! the helpers several of them use.
//!
//! - `render`: `penumbra render` (progressive, parts, aov), its signal handling and exit status.
//! - `merge`: `penumbra merge` of part files into an image.
//! - `compare`: `penumbra compare` of an image with a reference.
//! - `converge`: `penumbra converge`, convergence ladders against a reference.
//! - `report`: `penumbra report`, the interactive HTML comparison page.
//! - `output`: checking outputs are writable, and writing a render's image, preview and
//!   statistics (render and merge).

pub(crate) mod compare;
pub(crate) mod converge;
pub(crate) mod merge;
mod output;
pub(crate) mod render;
pub(crate) mod report;

use anyhow::{bail, Result};

fn parse_define(s: &str) -> Result<(String, String)> {
    match s.split_once('=') {
        Some((k, v)) if !k.is_empty() => Ok((k.to_string(), v.to_string())),
        _ => bail!("-D expects NAME=VALUE, got '{s}'"),
    }
}

fn file_name(p: &std::path::Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
