//! `penumbra converge`: ladders of sample counts rendered against a reference (error vs. spp
//! and time), over seeds and a swept parameter, written as CSV, JSON and a plot.

use super::{file_name, parse_define};
use anyhow::{bail, Context, Result};
use penumbra::display::{Frame, LiveView};
use penumbra::io::exr;
use penumbra::render::Job;
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct ConvergeArgs {
    /// The scene file (Mitsuba 3 XML).
    scene: PathBuf,
    /// The reference image (OpenEXR) at the scene's resolution; with variance channels and
    /// an `spp` header attribute (as Mitsuba references made by validation/mitsuba have) it
    /// also gives the noise floor and the z-test.
    #[arg(long, value_name = "EXR")]
    reference: PathBuf,
    /// Samples per pixel of the reference (default: its `spp` header attribute).
    #[arg(long, value_name = "N")]
    reference_spp: Option<f64>,
    /// The ladder: cumulative samples per pixel, each step continuing the previous one's
    /// samples (with stratified, multijitter, orthogonal and ldsampler: each step a render
    /// of its own at that count). `a,b,...,n` continues the progression of ratio b/a up to n.
    #[arg(long, value_name = "LIST", default_value = penumbra::study::experiment::DEFAULT_SPP)]
    spp: String,
    /// Independent ladders with seeds s, s+1, ..., s+K-1: mean and spread per step.
    #[arg(long, value_name = "K", default_value_t = 1)]
    seeds: u32,
    /// First seed (default: the sampler's seed).
    #[arg(long)]
    seed: Option<u64>,
    /// Sweep one scene parameter: NAME=v1,v2,... (a <default> of the scene, as -D sets it;
    /// the path integrator's max_depth / rr_depth; `sampler=independent,stratified,...`; or
    /// `integrator=path,bdpt,...`, switched as `render --integrator` does).
    #[arg(long, value_name = "NAME=V1,V2,...")]
    sweep: Option<String>,
    /// Set a scene parameter declared with <default name=...>, like Mitsuba's -D.
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    define: Vec<String>,
    /// Where converge.csv, converge.json and converge.png go.
    #[arg(long, value_name = "DIR", default_value = "converge-out")]
    out_dir: PathBuf,
    /// Stop each ladder after the first step that takes this long (seconds): compares
    /// settings of very different cost per sample (e.g. --sweep integrator=path,sppm) over
    /// the same time budget with one long ladder.
    #[arg(long, value_name = "SECONDS")]
    max_seconds: Option<f64>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Show each ladder as it converges in the tev image viewer listening at HOST:PORT: an
    /// image per ladder, named after the scene, the swept value and the seed, updated after
    /// its steps (at most every --display-every). If tev is not there or goes away: one
    /// warning, and the ladders go on.
    #[arg(long, value_name = "HOST:PORT", value_parser = super::render::parse_display_server)]
    display_server: Option<String>,
    /// With --display-server: the least time between two images sent (e.g. 0.5s, 10s).
    #[arg(long, value_name = "DURATION", value_parser = super::render::parse_duration,
          requires = "display_server")]
    display_every: Option<std::time::Duration>,
    /// `rgb` (default) or `spectral`: render every ladder in that mode, as `render --mode`
    /// (compare a spectral render with a spectral reference).
    #[arg(long, value_enum, default_value_t = super::render::ModeArg::Rgb)]
    mode: super::render::ModeArg,
    /// No per-step progress lines on stderr.
    #[arg(short, long)]
    quiet: bool,
}

pub(crate) fn run_converge(args: ConvergeArgs) -> Result<()> {
    use penumbra::study::experiment::{self as ex, SeriesResult, Sweep, SweepMode};
    let steps = ex::parse_spp_list(&args.spp).map_err(anyhow::Error::msg)?;
    if args.seeds == 0 {
        bail!("--seeds must be at least 1");
    }
    if let Some(v) = args.reference_spp {
        if !(v > 0.0 && v.is_finite()) {
            bail!("--reference-spp must be a positive number, got {v}");
        }
    }
    let sweep = args
        .sweep
        .as_deref()
        .map(Sweep::parse)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let defines = args
        .define
        .iter()
        .map(|d| parse_define(d))
        .collect::<Result<Vec<_>>>()?;
    let image = exr::read(&args.reference)?;
    let reference = ex::ReferenceImage {
        spp: args.reference_spp.or(image.spp()),
        image,
    };
    let (mut variants, mode) = ex::scene_variants(&args.scene, &defines, sweep.as_ref())?;
    for v in &mut variants {
        v.description.mode = args.mode.into();
    }
    let first_seed = match args.seed {
        Some(s) => s,
        None => variants[0].description.sensor.sampler.seed,
    };
    let seeds: Vec<u64> = (0..args.seeds as u64)
        .map(|k| first_seed.wrapping_add(k))
        .collect();
    let r = &reference.image;
    for v in &variants {
        let (width, height) = v.description.sensor.film.crop_size;
        if (width as usize, height as usize) != (r.width, r.height) {
            bail!(
                "the scene renders {}x{}, the reference is {}x{} (set the scene's resolution \
                 with -D, e.g. -D res={})",
                width,
                height,
                r.width,
                r.height,
                r.width
            );
        }
    }
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create {}", args.out_dir.display()))?;
    if !args.quiet {
        eprintln!(
            "reference {}: {}x{}, {}, {}",
            args.reference.display(),
            r.width,
            r.height,
            reference
                .spp
                .map_or("spp unknown".into(), |s| format!("{s} spp")),
            match reference.noise_floor() {
                Some(f) => format!("noise floor {f:.3e}"),
                None => "no variance channels: no noise floor, z-test with penumbra's variance \
                         for both terms"
                    .into(),
            }
        );
        if mode == Some(SweepMode::Integrator) {
            if let Some(s) = &sweep {
                eprintln!(
                    "the scene does not use ${0}: --sweep sets the path integrator's {0}",
                    s.name
                );
            }
        }
    }
    let live = args
        .display_server
        .as_deref()
        .map(|address| {
            LiveView::start(
                address,
                args.display_every
                    .unwrap_or(penumbra::display::DEFAULT_INTERVAL),
                std::sync::Arc::new(|m: &str| eprintln!("{m}")),
            )
        })
        .transpose()?;
    let stem = args
        .scene
        .file_stem()
        .map_or_else(|| "penumbra".into(), |s| s.to_string_lossy().into_owned());
    let mut results: Vec<SeriesResult> = Vec::new();
    for variant in &variants {
        let job = Job::build(&variant.description)?;
        if results.is_empty() {
            for w in &job.scene.warnings {
                eprintln!("warning: {w}");
            }
        }
        let mut runs = Vec::new();
        for &seed in &seeds {
            let label = if variant.label.is_empty() {
                format!("seed {seed}")
            } else {
                format!("{} seed {seed}", variant.label)
            };
            let quiet = args.quiet;
            let max_seconds = args.max_seconds;
            // The live image of this ladder: each step's film if one is due, and the last
            // step's once the ladder ends.
            let image_name = if variant.label.is_empty() {
                format!("{stem} seed {seed}")
            } else {
                format!("{stem} {} seed {seed}", variant.label)
            };
            let mut unsent: Option<Frame> = None;
            let run = ex::run_one(
                &job,
                &steps,
                seed,
                args.threads,
                &reference,
                max_seconds,
                &mut |s, film| {
                    if let Some(live) = &live {
                        let frame = Frame::from_film(&image_name, film, false);
                        if live.due() {
                            live.send(frame);
                            unsent = None;
                        } else {
                            unsent = Some(frame);
                        }
                    }
                    if !quiet {
                        eprintln!(
                            "  {label}: {:>6} spp {:>9.3} s {:>7.3} Mpath/s  RMSE {:.4e}  \
                         relMSE {:.4e}  efficiency {:.4e}{}",
                            s.spp,
                            s.seconds,
                            s.mpaths_per_second,
                            s.metrics.rmse,
                            s.metrics.rel_mse,
                            s.efficiency,
                            s.z_pass_rate
                                .map(|z| format!("  z-test pass {:.3}%", 100.0 * z))
                                .unwrap_or_default()
                        );
                    }
                },
            )?;
            if let (Some(live), Some(frame)) = (&live, unsent) {
                live.send(frame);
            }
            runs.push(run);
        }
        results.push(SeriesResult {
            label: variant.label.clone(),
            value: variant.value.clone(),
            runs,
        });
    }

    if let Some(live) = live {
        live.finish(None);
    }
    let command = std::iter::once("penumbra".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let info = ex::ExperimentInfo {
        scene: args.scene.to_string_lossy().into_owned(),
        reference: args.reference.to_string_lossy().into_owned(),
        reference_spp: reference.spp,
        reference_variance: r.variance.is_some(),
        noise_floor: reference.noise_floor(),
        width: r.width,
        height: r.height,
        defines: defines.iter().cloned().collect(),
        sweep: sweep.as_ref().map(|s| ex::SweepInfo {
            param: s.name.clone(),
            values: s.values.clone(),
            mode: match mode {
                Some(SweepMode::Integrator) => "integrator".into(),
                Some(SweepMode::Sampler) => "sampler".into(),
                Some(SweepMode::SwitchIntegrator) => "switch".into(),
                _ => "define".into(),
            },
        }),
        seeds: seeds.clone(),
        spp: steps.clone(),
        threads: args.threads,
        penumbra_version: penumbra::VERSION.to_string(),
        command,
    };
    let param = sweep.as_ref().map(|s| s.name.as_str());
    let csv_path = args.out_dir.join("converge.csv");
    let json_path = args.out_dir.join("converge.json");
    let png_path = args.out_dir.join("converge.png");
    std::fs::write(&csv_path, ex::to_csv(param, &results))
        .with_context(|| format!("cannot write {}", csv_path.display()))?;
    std::fs::write(&json_path, ex::to_json(&info, &results)?)
        .with_context(|| format!("cannot write {}", json_path.display()))?;
    let series: Vec<_> = results.iter().map(|r| r.plot_series()).collect();
    let title = format!(
        "{} vs. {}{}{}",
        file_name(&args.scene),
        file_name(&args.reference),
        sweep
            .as_ref()
            .map(|s| format!(", sweep of {}", s.name))
            .unwrap_or_default(),
        if seeds.len() > 1 {
            format!(", {} seeds (mean, min-max)", seeds.len())
        } else {
            String::new()
        }
    );
    penumbra::study::plot::write_series_png(
        &png_path,
        &penumbra::study::plot::SeriesPlot {
            title: &title,
            series: &series,
            floor: reference.noise_floor(),
            y_desc: "RMSE vs. reference",
        },
    )?;

    for res in &results {
        if !res.label.is_empty() {
            println!("\n## {}\n", res.label);
        }
        if seeds.len() > 1 {
            println!(
                "{} seeds ({}..={}); mean over seeds, RMSE as mean ± std [min, max]\n",
                seeds.len(),
                seeds[0],
                seeds[seeds.len() - 1]
            );
        }
        print!("{}", ex::table(res));
    }
    if results.len() > 1 {
        println!(
            "\n| {} | time (s) | RMSE | efficiency | slope |",
            param.unwrap_or("variant")
        );
        println!("|---|---:|---:|---:|---:|");
        for res in &results {
            let last = res.summary().pop();
            let slope = res.slope_spread();
            println!(
                "| {} | {} | {} | {} | {} |",
                res.value.as_deref().unwrap_or(""),
                last.as_ref()
                    .map_or("–".into(), |l| format!("{:.3}", l.seconds.mean)),
                last.as_ref()
                    .map_or("–".into(), |l| format!("{:.4e}", l.rmse.mean)),
                last.as_ref()
                    .map_or("–".into(), |l| format!("{:.4e}", l.efficiency.mean)),
                slope.map_or("n/a".into(), |s| format!("{:.3}", s.mean))
            );
        }
    }
    if !args.quiet {
        eprintln!(
            "wrote {}, {} and {}",
            csv_path.display(),
            json_path.display(),
            png_path.display()
        );
    }
    Ok(())
}
