//! Figures, written as PNG and SVG side by side.
//!
//! Text uses an embedded subset of DejaVu Sans (`host/assets`) through
//! plotters' `ab_glyph` backend, so plots render identically on machines
//! with no system fonts.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans-subset.ttf");
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

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
            .unwrap_or_else(|_| panic!("the embedded font is a valid TrueType file"));
    });
}

/// One histogram panel with an optional predicted density drawn over it.
#[derive(Debug, Clone)]
pub struct HistogramPanel {
    /// Title (e.g. the parameter name).
    pub title: String,
    /// Values to histogram.
    pub values: Vec<f64>,
    /// Predicted density N(mean, σ²) to overlay, scaled to the histogram.
    pub normal: Option<(f64, f64)>,
}

/// A grid of histogram panels (paper Fig. 7), written to `stem.png` and
/// `stem.svg`. Returns the paths written.
pub fn histogram_grid(
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
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
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
        .build_cartesian_2d(lo..hi, 0.0..ymax * 1.1)?;
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
pub struct LogLogPanel {
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
pub fn loglog_panels(
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
                (x0 / 1.2..x1 * 1.2).log_scale(),
                (y0 / 1.5..y1 * 1.5).log_scale(),
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
pub struct LinePanel {
    /// Panel title.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// Named curves of (x, y) points; non-finite points are skipped.
    pub series: Vec<(String, Vec<(f64, f64)>)>,
}

/// A grid of line-plot panels, written to `stem.png` and `stem.svg`.
/// Returns the paths written.
pub fn line_panels(
    stem: &Path,
    title: &str,
    panels: &[LinePanel],
    columns: usize,
) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let size = (420 * columns as u32, 40 + 260 * rows as u32);
    struct Lines<'a>(&'a str, &'a [LinePanel], usize, usize);
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

fn draw_lines<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[LinePanel],
    rows: usize,
    columns: usize,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(title, (FAMILY, 22))?;
    let cells = root.split_evenly((rows, columns));
    for (panel, area) in panels.iter().zip(cells.iter()) {
        let usable = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite();
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for &(x, y) in panel
            .series
            .iter()
            .flat_map(|(_, s)| s.iter().filter(|p| usable(p)))
        {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if !(x0.is_finite() && x1 > x0) {
            (x0, x1) = (x0.min(0.0), x0.max(0.0) + 1.0);
        }
        if !(y0.is_finite() && y1 > y0) {
            let c = if y0.is_finite() { y0 } else { 0.0 };
            (y0, y1) = (c - 1.0, c + 1.0);
        }
        let pad = 0.05 * (y1 - y0);
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FAMILY, 15))
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(54)
            .build_cartesian_2d(x0..x1, y0 - pad..y1 + pad)?;
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
        for (k, (name, s)) in panel.series.iter().enumerate() {
            let color = Palette99::pick(k).to_rgba();
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
        if panel.series.len() > 1 {
            chart
                .configure_series_labels()
                .label_font((FAMILY, 10))
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
        }
    }
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
}
