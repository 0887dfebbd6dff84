//! Convergence plots: log-log error against samples per pixel and against wall time, with
//! the ideal −1/2 line and the reference's noise floor, drawn with plotters into a memory
//! buffer and encoded as PNG with `image`.
//!
//! Text uses DejaVu Sans, committed in `assets/fonts/` (licence next to it) and compiled in,
//! so that plotting needs no system fonts.

use crate::error::{Error, Result};
use crate::study::convergence::{LadderStep, SlopeFit};
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

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

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// A white RGB8 buffer of [`PLOT_SIZE`] with a title and two side-by-side panels, drawn by
/// `draw(left, right)`.
fn two_panels(
    title: &str,
    title_size: u32,
    draw: impl FnOnce(&Area, &Area) -> Result<()>,
) -> Result<Vec<u8>> {
    register_font()?;
    let (w, h) = PLOT_SIZE;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let root = root.titled(title, (FONT, title_size)).map_err(plot_err)?;
        let (left, right) = root.split_horizontally(w / 2);
        draw(&left, &right)?;
        root.present().map_err(plot_err)?;
    }
    Ok(buf)
}

/// Draws the plot into an RGB8 buffer of [`PLOT_SIZE`].
pub fn draw_convergence(plot: &ConvergencePlot) -> Result<Vec<u8>> {
    two_panels(plot.title, 26, |left, right| {
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
            left,
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
            right,
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
        Ok(())
    })
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

/// A series of a multi-series convergence plot: one ladder, or the mean of several seeds'.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label (e.g. `max_depth=4: slope -0.49`).
    pub label: String,
    pub points: Vec<SeriesPoint>,
    /// Mean per-sample variance σ² of the series' images: its ideal curves are σ/√spp and
    /// σ·√(seconds per spp / seconds).
    pub sample_variance: f64,
}

/// One step of a [`Series`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeriesPoint {
    pub spp: f64,
    /// Wall time (mean over seeds).
    pub seconds: f64,
    /// RMSE (mean over seeds).
    pub rmse: f64,
    /// The spread over seeds drawn as a whisker (equal to `rmse` for one seed).
    pub rmse_min: f64,
    pub rmse_max: f64,
}

/// What a multi-series plot shows: every series' error against spp (left) and against wall
/// time (right), each with its ideal −1/2 line dashed in its colour, and the reference's
/// noise floor.
#[derive(Clone, Debug)]
pub struct SeriesPlot<'a> {
    pub title: &'a str,
    pub series: &'a [Series],
    pub floor: Option<f64>,
    /// The y axis description (e.g. `RMSE vs. reference`).
    pub y_desc: &'a str,
}

/// Series colours (Tableau 10), cycled.
const SERIES_COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Which axis a multi-series panel puts on x.
#[derive(Clone, Copy, PartialEq)]
enum XAxis {
    Spp,
    Seconds,
}

fn draw_series_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    plot: &SeriesPlot,
    axis: XAxis,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let x_of = |p: &SeriesPoint| match axis {
        XAxis::Spp => p.spp,
        XAxis::Seconds => p.seconds,
    };
    // The ideal curve of a series as a function of x.
    let ideal = |s: &Series, x: f64| -> f64 {
        match axis {
            XAxis::Spp => (s.sample_variance / x).sqrt(),
            XAxis::Seconds => {
                let t_spp = s.points.last().map_or(1.0, |p| p.seconds / p.spp.max(1.0));
                (s.sample_variance * t_spp / x).sqrt()
            }
        }
    };
    let (x0, x1) = log_range(plot.series.iter().flat_map(|s| s.points.iter().map(x_of)));
    let (y0, y1) = log_range(
        plot.series
            .iter()
            .flat_map(|s| {
                s.points
                    .iter()
                    .flat_map(|p| [p.rmse, p.rmse_min, p.rmse_max])
                    .chain([ideal(s, x0), ideal(s, x1)])
                    .collect::<Vec<_>>()
            })
            .chain(plot.floor),
    );
    let (caption, x_desc) = match axis {
        XAxis::Spp => ("error vs. samples per pixel", "samples per pixel"),
        XAxis::Seconds => ("error vs. wall time", "render time (s)"),
    };
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(plot.y_desc)
        .x_label_formatter(&sci)
        .y_label_formatter(&sci)
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .draw()
        .map_err(plot_err)?;
    let xs: Vec<f64> = (0..=64)
        .map(|i| x0 * (x1 / x0).powf(i as f64 / 64.0))
        .collect();
    for (i, s) in plot.series.iter().enumerate() {
        let colour = SERIES_COLOURS[i % SERIES_COLOURS.len()];
        chart
            .draw_series(DashedLineSeries::new(
                xs.iter().map(|&x| (x, ideal(s, x))),
                8,
                6,
                colour.mix(0.7).stroke_width(1),
            ))
            .map_err(plot_err)?;
        let pts: Vec<(f64, f64)> = s.points.iter().map(|p| (x_of(p), p.rmse)).collect();
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))
            .map_err(plot_err)?
            .label(s.label.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(pts.iter().map(|&q| Circle::new(q, 4, colour.filled())))
            .map_err(plot_err)?;
        chart
            .draw_series(
                s.points
                    .iter()
                    .filter(|p| p.rmse_max > p.rmse_min)
                    .map(|p| {
                        PathElement::new(
                            vec![(x_of(p), p.rmse_min), (x_of(p), p.rmse_max)],
                            colour.stroke_width(2),
                        )
                    }),
            )
            .map_err(plot_err)?;
    }
    // Legend entries for the line styles.
    chart
        .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
        .map_err(plot_err)?
        .label("dashed: ideal σ/√spp of each (slope −1/2)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(1)));
    if let Some(floor) = plot.floor {
        chart
            .draw_series(DashedLineSeries::new(
                [(x0, floor), (x1, floor)],
                3,
                4,
                BLACK.stroke_width(2),
            ))
            .map_err(plot_err)?
            .label(format!("reference noise floor {floor:.2e}"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font((FONT, 14))
        .draw()
        .map_err(plot_err)?;
    Ok(())
}

/// Draws a multi-series plot into an RGB8 buffer of [`PLOT_SIZE`].
pub fn draw_series_plot(plot: &SeriesPlot) -> Result<Vec<u8>> {
    two_panels(plot.title, 24, |left, right| {
        draw_series_panel(left, plot, XAxis::Spp)?;
        draw_series_panel(right, plot, XAxis::Seconds)?;
        Ok(())
    })
}

/// Draws a multi-series plot and writes it to `path` as PNG.
pub fn write_series_png(path: &Path, plot: &SeriesPlot) -> Result<()> {
    let (w, h) = PLOT_SIZE;
    save_rgb_png(path, w, h, draw_series_plot(plot)?)
}

fn save_rgb_png(path: &Path, w: u32, h: u32, buf: Vec<u8>) -> Result<()> {
    let err = |message: String| Error::Output {
        path: path.to_path_buf(),
        message,
    };
    let img = image::RgbImage::from_raw(w, h, buf).ok_or_else(|| err("plot buffer size".into()))?;
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| err(e.to_string()))
}

/// ColorBrewer's diverging RdBu (11 classes), from blue (−1) through near-white (0) to red
/// (+1).
const RDBU: [[u8; 3]; 11] = [
    [5, 48, 97],
    [33, 102, 172],
    [67, 147, 195],
    [146, 197, 222],
    [209, 229, 240],
    [247, 247, 247],
    [253, 219, 199],
    [244, 165, 130],
    [214, 96, 77],
    [178, 24, 43],
    [103, 0, 31],
];

/// Colour of the diff image's non-finite pixels: a green that the blue–red map never uses.
pub const NONFINITE_COLOUR: [u8; 3] = [0, 200, 0];

/// The diverging colour of `t` in [−1, 1] (clamped; NaN gives [`NONFINITE_COLOUR`]).
pub fn diverging_colour(t: f64) -> [u8; 3] {
    if t.is_nan() {
        return NONFINITE_COLOUR;
    }
    let x = (t.clamp(-1.0, 1.0) + 1.0) * 0.5 * (RDBU.len() - 1) as f64;
    let i = (x.floor() as usize).min(RDBU.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|c| {
        let (a, b) = (RDBU[i][c] as f64, RDBU[i + 1][c] as f64);
        (a + (b - a) * f).round() as u8
    })
}

/// What the false-colour diff image shows.
#[derive(Clone, Debug)]
pub struct DiffImage<'a> {
    pub width: usize,
    pub height: usize,
    /// Signed per-pixel difference (NaN for non-finite), row-major from the top row.
    pub values: &'a [f64],
    /// Half-range of the colour map: ±range is full blue / red; beyond it colours saturate.
    pub range: f64,
    /// Where the range comes from (shown under the colour bar).
    pub range_note: &'a str,
    /// One-line title above the image.
    pub title: &'a str,
}

/// Margin around the diff image, in pixels.
const DIFF_MARGIN: u32 = 10;
/// Height of the title line above the diff image.
const DIFF_TITLE: u32 = 34;
/// Width of the legend panel to the right of the diff image.
const DIFF_LEGEND: u32 = 250;
/// Minimum height of the image area (room for the colour bar and its notes).
const DIFF_MIN_HEIGHT: u32 = 360;
/// Small images are enlarged (nearest neighbour, integer factor) until their longer side is
/// at least this.
const DIFF_MIN_SIDE: usize = 384;

/// The integer enlargement of a `width`×`height` diff image.
pub fn diff_scale(width: usize, height: usize) -> usize {
    DIFF_MIN_SIDE.div_ceil(width.max(height).max(1)).max(1)
}

/// Size in pixels of the diff PNG of a `width`×`height` image: the image enlarged by
/// [`diff_scale`], a title line above, a legend panel of 250 pixels on the right, 10 pixel
/// margins; at least 360 pixels for the image area's height.
pub fn diff_png_size(width: usize, height: usize) -> (u32, u32) {
    let s = diff_scale(width, height);
    let (w, h) = ((width * s) as u32, (height * s) as u32);
    (
        DIFF_MARGIN + w + DIFF_LEGEND,
        DIFF_TITLE + h.max(DIFF_MIN_HEIGHT) + DIFF_MARGIN,
    )
}

/// Draws the diff image with its colour bar into an RGB8 buffer of [`diff_png_size`].
pub fn draw_diff(d: &DiffImage) -> Result<Vec<u8>> {
    register_font()?;
    if d.values.len() != d.width * d.height || d.width == 0 || d.height == 0 {
        return Err(Error::Invalid(
            "diff image: pixel count does not match the resolution".into(),
        ));
    }
    if !(d.range > 0.0 && d.range.is_finite()) {
        return Err(Error::Invalid(format!(
            "diff image: the colour range must be positive, got {}",
            d.range
        )));
    }
    let (w, h) = diff_png_size(d.width, d.height);
    let s = diff_scale(d.width, d.height);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let mut put = |x: u32, y: u32, c: [u8; 3]| {
        let i = ((y * w + x) * 3) as usize;
        buf[i..i + 3].copy_from_slice(&c);
    };
    for y in 0..d.height * s {
        for x in 0..d.width * s {
            let v = d.values[(y / s) * d.width + x / s];
            put(
                DIFF_MARGIN + x as u32,
                DIFF_TITLE + y as u32,
                diverging_colour(v / d.range),
            );
        }
    }
    // The colour bar: +range at the top, −range at the bottom.
    let bar_x = DIFF_MARGIN + (d.width * s) as u32 + 24;
    let (bar_w, bar_top, bar_len) = (26u32, DIFF_TITLE + 12, 200u32);
    for j in 0..bar_len {
        let t = 1.0 - 2.0 * j as f64 / (bar_len - 1) as f64;
        for i in 0..bar_w {
            put(bar_x + i, bar_top + j, diverging_colour(t));
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let text = |size: u32| TextStyle::from((FONT, size).into_font()).color(&BLACK);
        let left_mid = text(15).pos(plotters::style::text_anchor::Pos::new(
            plotters::style::text_anchor::HPos::Left,
            plotters::style::text_anchor::VPos::Center,
        ));
        root.draw(&Text::new(
            d.title.to_string(),
            (DIFF_MARGIN as i32, 8),
            text(17),
        ))
        .map_err(plot_err)?;
        root.draw(&Rectangle::new(
            [
                (bar_x as i32 - 1, bar_top as i32 - 1),
                ((bar_x + bar_w) as i32, (bar_top + bar_len) as i32),
            ],
            BLACK.stroke_width(1),
        ))
        .map_err(plot_err)?;
        let ticks = [
            (1.0, "(A > B)"),
            (0.5, ""),
            (0.0, ""),
            (-0.5, ""),
            (-1.0, "(A < B)"),
        ];
        for (t, note) in ticks {
            let y = bar_top as f64 + (1.0 - t) * 0.5 * (bar_len - 1) as f64;
            let y = y.round() as i32;
            let x = (bar_x + bar_w) as i32;
            root.draw(&PathElement::new(
                vec![(x, y), (x + 6, y)],
                BLACK.stroke_width(1),
            ))
            .map_err(plot_err)?;
            let v = t * d.range;
            let label = if t == 0.0 {
                "0".to_string()
            } else {
                format!("{v:+.3e} {note}")
            };
            root.draw(&Text::new(label, (x + 10, y), left_mid.clone()))
                .map_err(plot_err)?;
        }
        let finite: Vec<f64> = d.values.iter().copied().filter(|v| v.is_finite()).collect();
        let max_abs = finite.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let saturated = finite.iter().filter(|v| v.abs() > d.range).count();
        let nonfinite = d.values.len() - finite.len();
        let lines = [
            "Δ = A − B, mean over R, G, B".to_string(),
            format!("range ±{:.3e}", d.range),
            format!("({})", d.range_note),
            format!("max |Δ| {max_abs:.3e}"),
            format!("{saturated} px beyond the range"),
            format!("non-finite: green ({nonfinite} px)"),
        ];
        let x0 = bar_x as i32 - 10;
        for (k, line) in lines.iter().enumerate() {
            root.draw(&Text::new(
                line.clone(),
                (x0, (bar_top + bar_len + 14 + 20 * k as u32) as i32),
                text(14),
            ))
            .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    Ok(buf)
}

/// Draws the diff image and writes it to `path` as PNG.
pub fn write_diff_png(path: &Path, d: &DiffImage) -> Result<()> {
    let (w, h) = diff_png_size(d.width, d.height);
    save_rgb_png(path, w, h, draw_diff(d)?)
}
