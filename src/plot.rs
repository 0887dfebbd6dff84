//! Convergence plots: log-log error against samples per pixel and against wall time, with
//! the ideal −1/2 line and the reference's noise floor, drawn with plotters into a memory
//! buffer and encoded as PNG with `image`.
//!
//! Text uses DejaVu Sans, committed in `assets/fonts/` (licence next to it) and compiled in,
//! so that plotting needs no system fonts.

use crate::convergence::{LadderStep, SlopeFit};
use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

static DEJAVU_SANS: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// The font family name the plots use (registered on first use).
const FONT: &str = "sans-serif";

fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, DEJAVU_SANS).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::Invalid(
            "the bundled font assets/fonts/DejaVuSans.ttf cannot be parsed".into(),
        ))
    }
}

/// What a convergence plot shows.
#[derive(Clone, Debug)]
pub struct ConvergencePlot<'a> {
    pub title: &'a str,
    pub steps: &'a [LadderStep],
    /// Mean per-sample variance σ² of the renderer's image: the ideal curves are σ/√spp and
    /// σ·√(seconds per spp / seconds).
    pub sample_variance: f64,
    /// The slope fit (its floor is drawn, and its line over the steps it used).
    pub fit: Option<&'a SlopeFit>,
}

/// Width and height of a plot, in pixels: two panels side by side.
pub const PLOT_SIZE: (u32, u32) = (1400, 560);

fn plot_err(e: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("plotting failed: {e}"))
}

/// A logarithmic range with some margin around the positive finite values given.
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in values.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi > 0.0) {
        return (0.1, 10.0);
    }
    if hi <= lo {
        hi = lo * 10.0;
    }
    (lo / 1.6, hi * 1.6)
}

/// Scientific-notation tick labels (log axes span decades).
fn sci(v: &f64) -> String {
    if *v >= 1.0 && *v < 1e5 && v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.0e}")
    }
}

struct Panel<'a> {
    caption: String,
    x_desc: &'a str,
    /// (x, RMSE) measured.
    measured: Vec<(f64, f64)>,
    /// The ideal curve, as a function of x.
    ideal: Box<dyn Fn(f64) -> f64 + 'a>,
    ideal_label: String,
    /// The curve an unbiased renderer is expected to follow against a noisy reference:
    /// √(ideal² + floor²).
    expected: Option<Box<dyn Fn(f64) -> f64 + 'a>>,
    /// The fitted line (label, points).
    fitted: Option<(String, Vec<(f64, f64)>)>,
    floor: Option<f64>,
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Panel,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (x0, x1) = log_range(p.measured.iter().map(|q| q.0));
    let ideal_ends = [(p.ideal)(x0), (p.ideal)(x1)];
    let (y0, y1) = log_range(
        p.measured
            .iter()
            .map(|q| q.1)
            .chain(p.floor)
            .chain(ideal_ends.iter().copied()),
    );
    let mut chart = ChartBuilder::on(area)
        .caption(&p.caption, (FONT, 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(p.x_desc)
        .y_desc("RMSE vs. Mitsuba reference")
        .x_label_formatter(&sci)
        .y_label_formatter(&sci)
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .draw()
        .map_err(plot_err)?;
    let xs: Vec<f64> = (0..=64)
        .map(|i| x0 * (x1 / x0).powf(i as f64 / 64.0))
        .collect();
    chart
        .draw_series(DashedLineSeries::new(
            xs.iter().map(|&x| (x, (p.ideal)(x))),
            10,
            6,
            BLACK.stroke_width(2),
        ))
        .map_err(plot_err)?
        .label(p.ideal_label.as_str())
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(2)));
    if let Some(expected) = &p.expected {
        let gray = RGBColor(120, 120, 120);
        chart
            .draw_series(DottedLineSeries::new(
                xs.iter().map(|&x| (x, expected(x))),
                0,
                5,
                move |c| Circle::new(c, 1, gray.filled()),
            ))
            .map_err(plot_err)?
            .label("expected: √(ideal² + floor²)")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], gray.stroke_width(2))
            });
    }
    if let Some(floor) = p.floor {
        chart
            .draw_series(DashedLineSeries::new(
                [(x0, floor), (x1, floor)],
                6,
                6,
                RED.stroke_width(2),
            ))
            .map_err(plot_err)?
            .label(format!("reference noise floor {floor:.2e}"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], RED.stroke_width(2)));
    }
    if let Some((label, pts)) = &p.fitted {
        let green = RGBColor(0, 150, 60);
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), green.stroke_width(3)))
            .map_err(plot_err)?
            .label(label.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], green.stroke_width(3))
            });
    }
    chart
        .draw_series(LineSeries::new(
            p.measured.iter().copied(),
            BLUE.stroke_width(2),
        ))
        .map_err(plot_err)?
        .label("penumbra (measured)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLUE.stroke_width(2)));
    chart
        .draw_series(p.measured.iter().map(|&q| Circle::new(q, 4, BLUE.filled())))
        .map_err(plot_err)?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font((FONT, 15))
        .draw()
        .map_err(plot_err)?;
    Ok(())
}

/// Draws the plot into an RGB8 buffer of [`PLOT_SIZE`].
pub fn draw_convergence(plot: &ConvergencePlot) -> Result<Vec<u8>> {
    register_font()?;
    let (w, h) = PLOT_SIZE;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let root = root.titled(plot.title, (FONT, 26)).map_err(plot_err)?;
        let (left, right) = root.split_horizontally(w / 2);
        let sigma2 = plot.sample_variance;
        let floor = plot.fit.map(|f| f.floor).filter(|f| *f > 0.0);
        let used = plot.fit.map_or(0, |f| f.used);
        let line = plot.fit.and_then(|f| f.line);

        let by_spp: Vec<(f64, f64)> = plot
            .steps
            .iter()
            .map(|s| (s.spp as f64, s.metrics.rmse))
            .collect();
        let fitted_spp = line.filter(|_| used >= 2).map(|l| {
            let pts = plot.steps[..used]
                .iter()
                .map(|s| (s.spp as f64, l.eval(s.spp as f64)))
                .collect();
            (format!("fit over {used} steps: slope {:.3}", l.slope), pts)
        });
        draw_panel(
            &left,
            &Panel {
                caption: "error vs. samples per pixel".into(),
                x_desc: "samples per pixel",
                measured: by_spp,
                ideal: Box::new(move |spp| (sigma2 / spp).sqrt()),
                ideal_label: "ideal σ/√spp (slope −1/2)".into(),
                expected: floor.map(|f| {
                    Box::new(move |spp: f64| (sigma2 / spp + f * f).sqrt())
                        as Box<dyn Fn(f64) -> f64>
                }),
                fitted: fitted_spp,
                floor,
            },
        )?;

        // Seconds per sample per pixel, from the whole ladder: the ideal error after t
        // seconds is σ·√(t_spp / t).
        let last = plot.steps.last();
        let t_spp = last.map_or(1.0, |s| s.seconds / s.spp.max(1) as f64);
        let by_time: Vec<(f64, f64)> = plot
            .steps
            .iter()
            .map(|s| (s.seconds, s.metrics.rmse))
            .collect();
        draw_panel(
            &right,
            &Panel {
                caption: "error vs. wall time".into(),
                x_desc: "render time (s)",
                measured: by_time,
                ideal: Box::new(move |t| (sigma2 * t_spp / t).sqrt()),
                ideal_label: "ideal σ·√(t_spp/t) (slope −1/2)".into(),
                expected: floor.map(|f| {
                    Box::new(move |t: f64| (sigma2 * t_spp / t + f * f).sqrt())
                        as Box<dyn Fn(f64) -> f64>
                }),
                fitted: None,
                floor,
            },
        )?;
        root.present().map_err(plot_err)?;
    }
    Ok(buf)
}

/// Draws the plot and writes it to `path` as PNG.
pub fn write_convergence_png(path: &Path, plot: &ConvergencePlot) -> Result<()> {
    let buf = draw_convergence(plot)?;
    let (w, h) = PLOT_SIZE;
    let err = |message: String| Error::Output {
        path: path.to_path_buf(),
        message,
    };
    let img = image::RgbImage::from_raw(w, h, buf).ok_or_else(|| err("plot buffer size".into()))?;
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| err(e.to_string()))
}
