//! Files, backends, fonts, axis ranges and colours shared by the plots.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::{Error, Result};

/// One chart of a figure: its title and the axis ranges it drew.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// The chart's title.
    pub title: String,
    /// Range of the horizontal axis.
    pub x: (f64, f64),
    /// Range of the vertical axis.
    pub y: (f64, f64),
    /// Whether the vertical axis is logarithmic.
    pub log_y: bool,
}

/// What a plot drew: its panels, top to bottom.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Figure {
    /// The panels.
    pub panels: Vec<Panel>,
}

/// A plot that can be drawn on any plotters backend.
pub(crate) trait Draw {
    /// Draws on `root`; the backend's errors as text.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String>;
}

/// The family name of the embedded font.
pub(crate) const FONT: &str = "sans-serif";

/// Registers DejaVu Sans as the plots' font, once.
fn register_font() {
    static DONE: OnceLock<()> = OnceLock::new();
    DONE.get_or_init(|| {
        // The font is valid TrueType; a failure would only leave text undrawn.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

/// Draws `plot` into `path` (PNG or SVG by the extension) at `size` pixels.
pub(crate) fn render(plot: &impl Draw, path: &Path, size: (u32, u32)) -> Result<Figure> {
    register_font();
    let backend = |message: String| Error::Backend {
        path: path.display().to_string(),
        message,
    };
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            let figure = plot.draw(&root).map_err(backend)?;
            root.present().map_err(|e| backend(e.to_string()))?;
            Ok(figure)
        }
        Some("svg") => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            let figure = plot.draw(&root).map_err(backend)?;
            root.present().map_err(|e| backend(e.to_string()))?;
            Ok(figure)
        }
        _ => Err(Error::Format(path.display().to_string())),
    }
}

/// The error text of a backend error.
pub(crate) fn text<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// A linear axis range holding every finite value, padded by 5 % (a unit-wide range
/// around a constant; `(0, 1)` without finite values).
pub(crate) fn linear_range(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = finite_bounds(values);
    if lo > hi {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.5 * lo.abs().max(1.0)
    };
    (lo - pad, hi + pad)
}

/// A logarithmic axis range holding every positive finite value, widened to whole
/// decades (`(1e-16, 1)` without such values).
pub(crate) fn log_range(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = finite_bounds(values.into_iter().filter(|v| *v > 0.0));
    if lo > hi {
        return (1e-16, 1.0);
    }
    let lo = 10f64.powf(lo.log10().floor());
    let hi = 10f64.powf(hi.log10().ceil());
    if hi > lo { (lo, hi) } else { (lo / 10.0, hi * 10.0) }
}

fn finite_bounds(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
}

/// The colour of series `i` (ten well-separated hues, repeated).
pub(crate) fn color(i: usize) -> RGBColor {
    const COLORS: [RGBColor; 10] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
    ];
    COLORS[i % COLORS.len()]
}

/// Splits `points` at non-finite values into runs of finite points (a line is not drawn
/// across a missing value).
pub(crate) fn finite_runs(points: impl IntoIterator<Item = (f64, f64)>) -> Vec<Vec<(f64, f64)>> {
    let mut runs = vec![Vec::new()];
    for (x, y) in points {
        if x.is_finite() && y.is_finite() {
            runs.last_mut().expect("never empty").push((x, y));
        } else if !runs.last().expect("never empty").is_empty() {
            runs.push(Vec::new());
        }
    }
    runs.retain(|r| !r.is_empty());
    runs
}

/// Checks that every value is finite (`what` names the input in the error).
pub(crate) fn check_finite(what: &str, rows: &[Vec<f64>]) -> Result<()> {
    for (t, row) in rows.iter().enumerate() {
        if let Some(i) = row.iter().position(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!("{what}[{t}][{i}] is not finite ({})", row[i])));
        }
    }
    Ok(())
}

/// Draws the legend box of `chart` at `position` with `size`-pixel text.
pub(crate) fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    size: u32,
) -> std::result::Result<(), String> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font((FONT, size))
        .draw()
        .map_err(text)
}

/// A chart with linear axes.
pub(crate) type LinearChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Fills `root` white, writes `title` on its top line and returns the area below.
pub(crate) fn titled<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> std::result::Result<DrawingArea<DB, Shift>, String> {
    root.fill(&WHITE).map_err(text)?;
    let (top, body) = root.split_vertically(34);
    top.titled(title, (FONT, 22)).map_err(text)?;
    Ok(body)
}

/// A captioned panel of `area` with linear axes over `x` and `y` (`y_labels` pixels for
/// the vertical axis' labels); its mesh is drawn by the caller.
pub(crate) fn linear_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: &str,
    x: (f64, f64),
    y: (f64, f64),
    y_labels: u32,
) -> std::result::Result<LinearChart<'a, DB>, String> {
    ChartBuilder::on(area)
        .caption(caption, (FONT, 16))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(y_labels)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)
        .map_err(text)
}

/// Draws `points` as a solid line of colour `c`, with the legend entry `label` if given.
pub(crate) fn line<'a, DB: DrawingBackend + 'a, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'a, DB, CT>,
    points: Vec<(f64, f64)>,
    c: RGBColor,
    label: Option<String>,
) -> std::result::Result<(), String> {
    let series = chart
        .draw_series(LineSeries::new(points, c.stroke_width(2)))
        .map_err(text)?;
    if let Some(label) = label {
        series
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    Ok(())
}

/// A legend entry `label` with a dashed key of colour `c`, for dashed series.
pub(crate) fn dashed_key<'a, DB: DrawingBackend + 'a, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'a, DB, CT>,
    c: RGBColor,
    label: String,
) -> std::result::Result<(), String> {
    chart
        .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
        .map_err(text)?
        .label(label)
        .legend(move |(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new([(0, 0), (8, 0)], c.stroke_width(2))
                + PathElement::new([(13, 0), (20, 0)], c.stroke_width(2))
        });
    Ok(())
}
