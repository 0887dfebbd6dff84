//! Fits penumbra's whole sigmoid-polynomial coefficient table (Jakob and Hanika 2019) and
//! reports the cost: one column alone, then all 12288 columns on all threads. With a path
//! argument, also writes the table as little-endian f32 in rgb2spec's layout
//! (block, brightness, j, i, coefficient) for `tests/data/spectral/compare_table.py`.
//!
//! `cargo run --release --example spectral_table [-- table.bin]`

use std::time::Instant;

use penumbra::spectral::fit::{fit_column, RES};
use penumbra::spectral::upsample::{fit_whole_table, table_entry};

fn main() -> std::io::Result<()> {
    let t = Instant::now();
    let n = 16;
    for c in 0..n {
        std::hint::black_box(fit_column(c % 3, (c * 7) % RES, (c * 13) % RES));
    }
    println!(
        "one column: {:.2} ms (mean of {n})",
        t.elapsed().as_secs_f64() * 1e3 / n as f64
    );
    let t = Instant::now();
    fit_whole_table();
    println!(
        "whole table ({} columns) on {} threads: {:.2} s",
        3 * RES * RES,
        rayon::current_num_threads(),
        t.elapsed().as_secs_f64()
    );
    if let Some(path) = std::env::args().nth(1) {
        let mut bytes = Vec::with_capacity(3 * RES * RES * RES * 12);
        for l in 0..3 {
            for k in 0..RES {
                for j in 0..RES {
                    for i in 0..RES {
                        for c in table_entry(l, k, j, i) {
                            bytes.extend_from_slice(&c.to_le_bytes());
                        }
                    }
                }
            }
        }
        std::fs::write(path, bytes)?;
    }
    Ok(())
}
