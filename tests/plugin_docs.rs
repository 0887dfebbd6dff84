//! The BSDF documentation is generated from the plugins' parameter tables (issue 41):
//! docs/bsdfs.md is the output of `penumbra plugins`, and the README's bsdf row names every
//! plugin that has a table. Regenerate with `cargo run --release -- plugins > docs/bsdfs.md`.

use penumbra::bsdf::{plugin::markdown, TABLE_PLUGINS};
use std::path::Path;

fn repo_file(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn docs_bsdfs_is_the_tables_output() {
    assert!(
        repo_file("docs/bsdfs.md") == markdown(),
        "docs/bsdfs.md is not what the tables generate: run \
         `cargo run --release -- plugins > docs/bsdfs.md`"
    );
}

#[test]
fn readme_names_every_table_plugin() {
    let readme = repo_file("README.md");
    let row = readme
        .lines()
        .find(|l| l.starts_with("| bsdf |"))
        .expect("the README's subset table has a bsdf row");
    assert!(row.contains("docs/bsdfs.md"), "{row}");
    for p in TABLE_PLUGINS {
        assert!(
            row.contains(&format!("`{}`", p.name)),
            "the README's bsdf row does not name {}",
            p.name
        );
    }
}
