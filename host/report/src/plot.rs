//! Figures, written as PNG and SVG side by side.
//!
//! Text uses an embedded subset of DejaVu Sans (`host/report/assets`:
//! Latin, Greek, punctuation, arrows, mathematical operators; no combining
//! marks) through plotters' `ab_glyph` backend, so plots render identically
//! on machines with no system fonts. A character outside the subset renders
//! as a blank: figure text keeps to it (tested against the font's cmap).

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor;

/// The embedded font (DejaVu Sans subset), as registered for every figure.
pub(crate) const FONT: &[u8] = include_bytes!("../assets/DejaVuSans-subset.ttf");
const FAMILY: &str = "sans-serif";

/// A figure could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write the figure {}: {message}", path.display())]
pub struct PlotError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub message: String,
}

/// The largest magnitude an axis may reach, and the smallest span it may
/// have relative to its magnitude: beyond either, plotters' tick search
/// does not end (a value of 1e308, times in ns next to seconds).
const AXIS_MAX: f64 = 1e100;
const AXIS_MIN_SPAN: f64 = 1e-10;

/// Refuses an axis `lo..hi` that cannot be drawn (`log`: a log scale, so
/// `lo > 0` and at most 100 decades).
fn axis(what: &str, lo: f64, hi: f64, log: bool) -> Result<std::ops::Range<f64>, String> {
    let span = hi - lo;
    let magnitude = lo.abs().max(hi.abs());
    let drawable = lo.is_finite()
        && hi.is_finite()
        && span.is_finite()
        && span > AXIS_MIN_SPAN * magnitude
        && magnitude <= AXIS_MAX
        && (!log || (lo > 0.0 && hi / lo <= 1e100));
    if drawable {
        Ok(lo..hi)
    } else {
        Err(format!(
            "the {what} axis would run from {lo:e} to {hi:e}, which cannot be drawn (a value out of its range in the input?)"
        ))
    }
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
            .unwrap_or_else(|_| panic!("the embedded font is a valid TrueType file"));
    });
}

/// One histogram panel with an optional predicted density drawn over it.
#[derive(Debug, Clone)]
pub(crate) struct HistogramPanel {
    /// Title (e.g. the parameter name).
    pub title: String,
    /// Values to histogram.
    pub values: Vec<f64>,
    /// Predicted density N(mean, σ²) to overlay, scaled to the histogram.
    pub normal: Option<(f64, f64)>,
}

/// A grid of histogram panels (paper Fig. 7), written to `stem.png` and
/// `stem.svg`. Returns the paths written.
pub(crate) fn histogram_grid(
    stem: &Path,
    title: &str,
    panels: &[HistogramPanel],
    columns: usize,
) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let size = (300 * columns as u32, 40 + 220 * rows as u32);
    struct Grid<'a>(&'a str, &'a [HistogramPanel], usize, usize);
    impl Figure for Grid<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
        where
            DB::ErrorType: 'static,
        {
            draw_grid(root, self.0, self.1, self.2, self.3)
        }
    }
    write_png_svg(stem, size, &Grid(title, panels, rows, columns))
}

type DrawResult = Result<(), Box<dyn std::error::Error + 'static>>;

/// A figure that can draw itself on any plotters backend.
trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static;
}

/// Draw `figure` into `stem.png` and `stem.svg`; the paths written.
fn write_png_svg(
    stem: &Path,
    size: (u32, u32),
    figure: &impl Figure,
) -> Result<Vec<PathBuf>, PlotError> {
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    let err = |path: &Path, e: &dyn std::fmt::Display| PlotError {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        figure.draw(&root).map_err(|e| err(&png, &e))?;
        root.present().map_err(|e| err(&png, &e))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        figure.draw(&root).map_err(|e| err(&svg, &e))?;
        root.present().map_err(|e| err(&svg, &e))?;
    }
    Ok(vec![png, svg])
}

fn draw_grid<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[HistogramPanel],
    rows: usize,
    columns: usize,
) -> Result<(), Box<dyn std::error::Error + 'static>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(title, (FAMILY, 22))?;
    let cells = root.split_evenly((rows, columns));
    for (panel, area) in panels.iter().zip(cells.iter()) {
        draw_histogram(area, panel)?;
    }
    Ok(())
}

fn draw_histogram<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &HistogramPanel,
) -> Result<(), Box<dyn std::error::Error + 'static>>
where
    DB::ErrorType: 'static,
{
    let finite: Vec<f64> = panel
        .values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    let (mut lo, mut hi) = finite
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if let Some((m, s)) = panel.normal {
        lo = lo.min(m - 3.5 * s);
        hi = hi.max(m + 3.5 * s);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        (lo, hi) = (-1.0, 1.0);
    } else if hi <= lo {
        lo -= 1.0;
        hi += 1.0;
    }
    let bins = ((finite.len() as f64).sqrt().ceil() as usize).clamp(5, 40);
    let width = (hi - lo) / bins as f64;
    let mut counts = vec![0usize; bins];
    for v in &finite {
        let k = (((v - lo) / width) as usize).min(bins - 1);
        counts[k] += 1;
    }
    // as a density, so the predicted curve shares the axis
    let scale = 1.0 / (finite.len().max(1) as f64 * width);
    let mut ymax = counts.iter().map(|&c| c as f64 * scale).fold(0.0, f64::max);
    if let Some((_, s)) = panel.normal {
        ymax = ymax.max(1.0 / (s * (2.0 * std::f64::consts::PI).sqrt()));
    }
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FAMILY, 15))
        .margin(6)
        .x_label_area_size(22)
        .y_label_area_size(34)
        .build_cartesian_2d(
            axis(&panel.title, lo, hi, false)?,
            axis(
                &panel.title,
                0.0,
                if ymax > 0.0 { ymax * 1.1 } else { 1.0 },
                false,
            )?,
        )?;
    chart
        .configure_mesh()
        .x_labels(4)
        .y_labels(3)
        .label_style((FAMILY, 10))
        .disable_mesh()
        .draw()?;
    chart.draw_series(counts.iter().enumerate().map(|(k, &c)| {
        let x0 = lo + k as f64 * width;
        Rectangle::new(
            [(x0, 0.0), (x0 + width, c as f64 * scale)],
            BLUE.mix(0.4).filled(),
        )
    }))?;
    if let Some((m, s)) = panel.normal {
        let n = 200;
        chart.draw_series(LineSeries::new(
            (0..=n).map(|i| {
                let x = lo + (hi - lo) * i as f64 / n as f64;
                let z = (x - m) / s;
                (
                    x,
                    (-0.5 * z * z).exp() / (s * (2.0 * std::f64::consts::PI).sqrt()),
                )
            }),
            RED.stroke_width(2),
        ))?;
    }
    Ok(())
}

/// One panel of log-log curves (e.g. Allan deviations).
#[derive(Debug, Clone)]
pub(crate) struct LogLogPanel {
    /// Panel title.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// Named curves of (x, y) points; non-positive or non-finite points are skipped.
    pub series: Vec<(String, Vec<(f64, f64)>)>,
}

/// Panels of log-log line plots side by side, written to `stem.png` and
/// `stem.svg`. Returns the paths written.
pub(crate) fn loglog_panels(
    stem: &Path,
    title: &str,
    panels: &[LogLogPanel],
) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let columns = panels.len().max(1);
    let size = (480 * columns as u32, 420);
    struct LogLog<'a>(&'a str, &'a [LogLogPanel]);
    impl Figure for LogLog<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
        where
            DB::ErrorType: 'static,
        {
            draw_loglog(root, self.0, self.1)
        }
    }
    write_png_svg(stem, size, &LogLog(title, panels))
}

fn draw_loglog<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[LogLogPanel],
) -> Result<(), Box<dyn std::error::Error + 'static>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(title, (FAMILY, 22))?;
    let cells = root.split_evenly((1, panels.len().max(1)));
    for (panel, area) in panels.iter().zip(cells.iter()) {
        let usable = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0;
        let points = panel
            .series
            .iter()
            .flat_map(|(_, s)| s.iter().filter(|p| usable(p)));
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        for &(x, y) in points {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if !(x0.is_finite() && x1 > x0) {
            (x0, x1) = (0.1, 10.0);
        }
        if !(y0.is_finite() && y1 > y0) {
            (y0, y1) = (
                if y0.is_finite() { y0 / 10.0 } else { 0.1 },
                y1.max(1.0) * 10.0,
            );
        }
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FAMILY, 16))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(
                axis(&panel.title, x0 / 1.2, x1 * 1.2, true)?.log_scale(),
                axis(&panel.title, y0 / 1.5, y1 * 1.5, true)?.log_scale(),
            )?;
        chart
            .configure_mesh()
            .x_desc(panel.x_label.as_str())
            .y_desc(panel.y_label.as_str())
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .label_style((FAMILY, 11))
            .axis_desc_style((FAMILY, 12))
            .draw()?;
        for (k, (name, s)) in panel.series.iter().enumerate() {
            let color = Palette99::pick(k).to_rgba();
            chart
                .draw_series(LineSeries::new(
                    s.iter().copied().filter(usable),
                    color.stroke_width(2),
                ))?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .label_font((FAMILY, 12))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// One panel of line curves on linear axes (time series, convergence).
#[derive(Debug, Clone)]
pub(crate) struct LinePanel {
    /// Panel title.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// Named curves of (x, y) points; non-finite points are skipped.
    pub series: Vec<(String, Vec<(f64, f64)>)>,
}

/// A shaded band around a panel's curves: (x, lower, upper) points, e.g.
/// the ±1σ of a noise model around residuals.
#[derive(Debug, Clone)]
pub struct Band {
    /// Legend text.
    pub label: String,
    /// (x, lower, upper), in x order; non-finite points are skipped.
    pub points: Vec<(f64, f64, f64)>,
}

/// A grid of line-plot panels, written to `stem.png` and `stem.svg`.
/// Returns the paths written.
pub(crate) fn line_panels(
    stem: &Path,
    title: &str,
    panels: &[LinePanel],
    columns: usize,
) -> Result<Vec<PathBuf>, PlotError> {
    let panels: Vec<(&LinePanel, Option<&Band>)> = panels.iter().map(|p| (p, None)).collect();
    banded_line_panels(stem, title, &panels, columns)
}

/// [`line_panels`] with an optional shaded [`Band`] behind each panel's
/// curves (in the legend).
pub(crate) fn banded_line_panels(
    stem: &Path,
    title: &str,
    panels: &[(&LinePanel, Option<&Band>)],
    columns: usize,
) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let size = (420 * columns as u32, 40 + 260 * rows as u32);
    struct Lines<'a>(
        &'a str,
        &'a [(&'a LinePanel, Option<&'a Band>)],
        usize,
        usize,
    );
    impl Figure for Lines<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
        where
            DB::ErrorType: 'static,
        {
            draw_lines(root, self.0, self.1, self.2, self.3)
        }
    }
    write_png_svg(stem, size, &Lines(title, panels, rows, columns))
}

/// The x and y ranges (x0, x1, y0, y1) of finite `points`, widened to a
/// unit range around the data where they have none (one point, or none).
fn data_range(points: impl Iterator<Item = (f64, f64)>) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for (x, y) in points {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if !(x0.is_finite() && x1 > x0) {
        (x0, x1) = (x0.min(0.0), x0.max(0.0) + 1.0);
    }
    if !(y0.is_finite() && y1 > y0) {
        let c = if y0.is_finite() { y0 } else { 0.0 };
        (y0, y1) = (c - 1.0, c + 1.0);
    }
    (x0, x1, y0, y1)
}

fn draw_lines<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[(&LinePanel, Option<&Band>)],
    rows: usize,
    columns: usize,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(title, (FAMILY, 22))?;
    let cells = root.split_evenly((rows, columns));
    for (&(panel, band), area) in panels.iter().zip(cells.iter()) {
        let usable = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite();
        let band_points: Vec<(f64, f64, f64)> = band
            .map(|b| {
                b.points
                    .iter()
                    .copied()
                    .filter(|&(x, lo, hi)| x.is_finite() && lo.is_finite() && hi.is_finite())
                    .collect()
            })
            .unwrap_or_default();
        let band_ends = band_points
            .iter()
            .flat_map(|&(x, lo, hi)| [(x, lo), (x, hi)]);
        let (x0, x1, y0, y1) = data_range(
            panel
                .series
                .iter()
                .flat_map(|(_, s)| s.iter().copied().filter(usable))
                .chain(band_ends),
        );
        let pad = 0.05 * (y1 - y0);
        // room for the legend above the curves
        let top = if band.is_some() { 0.35 } else { 0.05 } * (y1 - y0);
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FAMILY, 15))
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(54)
            .build_cartesian_2d(
                axis(&panel.title, x0, x1, false)?,
                axis(&panel.title, y0 - pad, y1 + top, false)?,
            )?;
        chart
            .configure_mesh()
            .x_desc(panel.x_label.as_str())
            .y_desc(panel.y_label.as_str())
            .x_labels(5)
            .y_labels(5)
            .label_style((FAMILY, 10))
            .axis_desc_style((FAMILY, 11))
            .disable_mesh()
            .draw()?;
        let edge = RGBColor(0, 110, 40);
        if !band_points.is_empty() {
            let outline: Vec<(f64, f64)> = band_points
                .iter()
                .map(|&(x, _, hi)| (x, hi))
                .chain(band_points.iter().rev().map(|&(x, lo, _)| (x, lo)))
                .collect();
            chart.draw_series(std::iter::once(Polygon::new(
                outline,
                RGBColor(120, 200, 140).mix(0.35).filled(),
            )))?;
        }
        for (k, (name, s)) in panel.series.iter().enumerate() {
            // behind the band's edges, lighter, when there is a band
            let alpha = if band.is_some() { 0.55 } else { 1.0 };
            let color = Palette99::pick(k).mix(alpha);
            chart
                .draw_series(LineSeries::new(
                    s.iter().copied().filter(usable),
                    color.stroke_width(1),
                ))?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
                });
        }
        if let (Some(b), false) = (band, band_points.is_empty()) {
            for side in [1usize, 2] {
                let line = band_points
                    .iter()
                    .map(move |p| (p.0, if side == 1 { p.1 } else { p.2 }));
                let series = chart.draw_series(LineSeries::new(line, edge.stroke_width(2)))?;
                if side == 1 {
                    series.label(b.label.as_str()).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 16, y)], edge.stroke_width(2))
                    });
                }
            }
        }
        if panel.series.len() + usize::from(band.is_some()) > 1 {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .label_font((FAMILY, 10))
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
        }
    }
    Ok(())
}

/// One bar of [`log_bars`].
#[derive(Debug, Clone)]
pub(crate) struct Bar {
    /// The name on the axis.
    pub label: String,
    /// The bar's value (> 0); `None` (or not positive): no bar, `note` instead.
    pub value: Option<f64>,
    /// Text shown in place of a missing bar (e.g. "frozen").
    pub note: String,
}

/// A group of bars under a heading.
#[derive(Debug, Clone)]
pub(crate) struct BarGroup {
    /// The heading.
    pub name: String,
    /// Its bars, top to bottom.
    pub bars: Vec<Bar>,
}

/// The bars' colour per group (dark enough on white).
const GROUP_COLOURS: [RGBColor; 5] = [
    RGBColor(200, 60, 50),
    RGBColor(40, 140, 70),
    RGBColor(220, 130, 20),
    RGBColor(40, 100, 190),
    RGBColor(130, 70, 170),
];

/// Height of one bar or heading row, px.
const BAR_ROW: u32 = 17;

/// Horizontal bars on a log axis, one row per bar with its label on the
/// axis, in groups under a heading (coloured per group), each bar drawn from
/// `reference` (e.g. 1 = the prior) to its value. Written to `stem.png` and
/// `stem.svg`; returns the paths written.
pub(crate) fn log_bars(
    stem: &Path,
    title: &str,
    x_label: &str,
    reference: f64,
    groups: &[BarGroup],
) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let rows: u32 = groups.iter().map(|g| 1 + g.bars.len() as u32).sum();
    let size = (900, 110 + BAR_ROW * rows.max(1));
    struct Bars<'a>(&'a str, &'a str, f64, &'a [BarGroup]);
    impl Figure for Bars<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
        where
            DB::ErrorType: 'static,
        {
            draw_bars(root, self.0, self.1, self.2, self.3)
        }
    }
    write_png_svg(stem, size, &Bars(title, x_label, reference, groups))
}

/// A log axis tick: plain decimals from 0.001 to 9999, else `1e-5`.
fn log_tick(v: f64) -> String {
    if (1e-3..1e4).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// A value to two significant digits: `0.42`, `0.0031`, `2.6e-5`.
fn log_tick_2(v: f64) -> String {
    if (1e-3..1e3).contains(&v.abs()) {
        let digits = (1 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.1e}")
    }
}

fn draw_bars<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    x_label: &str,
    reference: f64,
    groups: &[BarGroup],
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let titled = root.titled(title, (FAMILY, 20))?;
    let value = |b: &Bar| b.value.filter(|v| v.is_finite() && *v > 0.0);
    let (mut lo, mut hi) = (reference, reference);
    for v in groups.iter().flat_map(|g| g.bars.iter().filter_map(value)) {
        (lo, hi) = (lo.min(v), hi.max(v));
    }
    // from the decade below the smallest value, at least one decade
    let lo = 10f64.powf(lo.log10().floor()).min(hi / 10.0);
    let hi = hi * 1.6;
    let n: usize = groups.iter().map(|g| 1 + g.bars.len()).sum();
    let longest = groups
        .iter()
        .flat_map(|g| g.bars.iter().map(|b| b.label.chars().count()))
        .max()
        .unwrap_or(4);
    let label_width = (14 + 8 * longest as u32).clamp(60, 320);
    let mut chart = ChartBuilder::on(&titled)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(label_width)
        .build_cartesian_2d(
            axis(title, lo, hi, true)?.log_scale(),
            0f64..n.max(1) as f64,
        )?;
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(0)
        .x_desc(x_label)
        .x_label_formatter(&|v| log_tick(*v))
        .label_style((FAMILY, 11))
        .axis_desc_style((FAMILY, 12))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let name_style = TextStyle::from((FAMILY, 12).into_font()).pos(text_anchor::Pos::new(
        text_anchor::HPos::Right,
        text_anchor::VPos::Center,
    ));
    let head_style = TextStyle::from((FAMILY, 13).into_font()).pos(text_anchor::Pos::new(
        text_anchor::HPos::Left,
        text_anchor::VPos::Center,
    ));
    let note_style =
        TextStyle::from((FAMILY, 11).into_font())
            .color(&BLACK)
            .pos(text_anchor::Pos::new(
                text_anchor::HPos::Right,
                text_anchor::VPos::Center,
            ));
    // row k (0 = top) spans y ∈ [n − k − 1, n − k]
    let mut k = 0usize;
    for (g, group) in groups.iter().enumerate() {
        let color = GROUP_COLOURS[g % GROUP_COLOURS.len()];
        let y = (n - k - 1) as f64;
        chart.draw_series(std::iter::once(Rectangle::new(
            [(lo, y), (hi, y + 1.0)],
            RGBColor(235, 235, 235).filled(),
        )))?;
        let (_, py) = chart.backend_coord(&(lo, y + 0.5));
        let (px, _) = chart.backend_coord(&(lo, y));
        root.draw(&Text::new(
            group.name.clone(),
            (px - label_width as i32 + 4, py),
            head_style.clone(),
        ))?;
        k += 1;
        for bar in &group.bars {
            let y = (n - k - 1) as f64;
            let (px, py) = chart.backend_coord(&(lo, y + 0.5));
            root.draw(&Text::new(
                bar.label.clone(),
                (px - 6, py),
                name_style.clone(),
            ))?;
            match value(bar) {
                Some(v) => {
                    chart.draw_series(std::iter::once(Rectangle::new(
                        [(v, y + 0.15), (reference, y + 0.85)],
                        color.filled(),
                    )))?;
                    // the value, at the bar's end away from the reference
                    let (bx, _) = chart.backend_coord(&(v.min(reference), y));
                    root.draw(&Text::new(log_tick_2(v), (bx - 3, py), note_style.clone()))?;
                }
                None => {
                    let (rx, _) = chart.backend_coord(&(hi, y));
                    root.draw(&Text::new(
                        bar.note.clone(),
                        (rx - 4, py),
                        note_style.clone(),
                    ))?;
                }
            }
            k += 1;
        }
    }
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(reference, 0.0), (reference, n as f64)],
        BLACK.stroke_width(1),
    )))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_png_and_svg_with_text() {
        let dir = tempfile::tempdir().unwrap();
        let panels: Vec<HistogramPanel> = (0..3)
            .map(|k| HistogramPanel {
                title: format!("eps_{k}_1 [mm]"),
                values: (0..200)
                    .map(|i| ((i * 37 % 101) as f64 / 50.0 - 1.0) * (k + 1) as f64)
                    .collect(),
                normal: Some((0.0, 0.6 * (k + 1) as f64)),
            })
            .collect();
        let files = histogram_grid(&dir.path().join("hist"), "error — σ", &panels, 2).unwrap();
        assert_eq!(files.len(), 2);
        let png = std::fs::read(&files[0]).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let svg = std::fs::read_to_string(&files[1]).unwrap();
        assert!(
            svg.contains("<svg") && svg.contains("eps_2_1"),
            "titles are in the SVG"
        );
    }

    #[test]
    fn writes_loglog_panels() {
        let dir = tempfile::tempdir().unwrap();
        let curve: Vec<(f64, f64)> = (0..10)
            .map(|k| {
                let t = 0.01 * 2f64.powi(k);
                (t, 0.02 / t.sqrt())
            })
            .collect();
        let panels = vec![
            LogLogPanel {
                title: "accelerometer".into(),
                x_label: "tau [s]".into(),
                y_label: "sigma".into(),
                series: vec![
                    ("ax".into(), curve.clone()),
                    ("bad".into(), vec![(0.0, -1.0)]),
                ],
            },
            LogLogPanel {
                title: "empty".into(),
                x_label: "tau [s]".into(),
                y_label: "sigma".into(),
                series: vec![],
            },
        ];
        let files = loglog_panels(&dir.path().join("allan"), "Allan deviation", &panels).unwrap();
        let png = std::fs::read(&files[0]).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let svg = std::fs::read_to_string(&files[1]).unwrap();
        assert!(svg.contains("accelerometer") && svg.contains("ax"));
    }

    /// Issue 41: an axis over 1e308 or a span lost in its magnitude is
    /// refused at once (plotters' tick search would not end).
    #[test]
    fn undrawable_axes_are_refused_not_a_hang() {
        let dir = tempfile::tempdir().unwrap();
        let panel = |points: Vec<(f64, f64)>| LinePanel {
            title: "residual".into(),
            x_label: "t [s]".into(),
            y_label: "r".into(),
            series: vec![("r".into(), points)],
        };
        let start = std::time::Instant::now();
        for (points, want) in [
            (
                vec![(0.0, -1e308), (1.0, 1e308)],
                "the residual axis would run from",
            ),
            (
                vec![(1.7e18, 0.0), (1.7e18 + 256.0, 1.0)],
                "cannot be drawn",
            ),
        ] {
            let e = line_panels(&dir.path().join("r"), "r", &[panel(points)], 1)
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{e}");
        }
        let bars = [BarGroup {
            name: "IMU".into(),
            bars: vec![Bar {
                label: "k_a_x".into(),
                value: Some(1e308),
                note: String::new(),
            }],
        }];
        let e = log_bars(&dir.path().join("b"), "σ", "σ / prior σ", 1.0, &bars)
            .unwrap_err()
            .to_string();
        assert!(e.contains("σ axis would run from"), "{e}");
        assert!(start.elapsed().as_secs() < 5, "{:?}", start.elapsed());
    }
}
