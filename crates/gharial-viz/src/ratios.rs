//! Time ratios against the peers, from one run of the peer harness: bars of gharial's
//! solve time over a peer's, per problem and solver, on a log scale.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use serde::Deserialize;

use crate::figure::{Draw, FONT, Figure, Panel, color, legend, log_range, render, text};
use crate::{Error, Result};

/// One bar: gharial's time over a peer's on a problem, for one solver.
#[derive(Debug, Clone, PartialEq)]
pub struct Ratio {
    /// The harness's problem name.
    pub problem: String,
    /// What is compared, e.g. `FDDP / crocoddyl`.
    pub pair: String,
    /// gharial's median solve time over the peer's.
    pub ratio: f64,
}

/// The fields of a harness record that the ratios use.
#[derive(Debug, Deserialize)]
struct Record {
    problem: String,
    lib: String,
    solver: String,
    converged: bool,
    time_ms: Option<f64>,
}

/// The ratios of one harness run (its merged JSON lines, gharial's records included):
/// for every problem and solver that both gharial and a peer solved (converged), the
/// ratio of gharial's median time to the peer's, peers with the same solver name
/// (`ProxDDP` against aligator's, `FDDP` against crocoddyl's and aligator's, `SQP` and
/// `CSQP` against mim_solvers', ...). Ordered by problem, then pair.
///
/// # Errors
/// A line that is not a harness record, or no gharial record with a peer to compare.
pub fn ratios_from_harness(jsonl: &str) -> Result<Vec<Ratio>> {
    let mut records = Vec::new();
    for (n, line) in jsonl.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let r: Record =
            serde_json::from_str(line).map_err(|e| Error::Invalid(format!("harness line {}: {e}", n + 1)))?;
        records.push(r);
    }
    let solved = |r: &&Record| r.converged && r.time_ms.is_some_and(|t| t.is_finite() && t > 0.0);
    let mut out = Vec::new();
    for g in records.iter().filter(|r| r.lib == "gharial").filter(solved) {
        for p in records.iter().filter(|r| r.lib != "gharial").filter(solved) {
            if p.problem == g.problem && p.solver == g.solver {
                out.push(Ratio {
                    problem: g.problem.clone(),
                    pair: format!("{} / {}", g.solver, p.lib),
                    ratio: g.time_ms.unwrap_or(f64::NAN) / p.time_ms.unwrap_or(f64::NAN),
                });
            }
        }
    }
    if out.is_empty() {
        return Err(Error::Invalid(
            "no problem was solved by gharial and a peer with the same solver in this harness run".into(),
        ));
    }
    out.sort_by(|a, b| (&a.problem, &a.pair).cmp(&(&b.problem, &b.pair)));
    Ok(out)
}

/// Draws the ratios as grouped bars (one group per problem, one colour per pair) on a
/// log scale with the line of equal times. Writes `file` (`.png` or `.svg`).
///
/// # Errors
/// No ratios, a ratio that is not positive and finite, or a file that cannot be written.
pub fn ratios(bars: &[Ratio], title: &str, file: &Path) -> Result<Figure> {
    if bars.is_empty() {
        return Err(Error::Invalid("ratio plot: no ratios".into()));
    }
    if let Some(b) = bars.iter().find(|b| !(b.ratio.is_finite() && b.ratio > 0.0)) {
        return Err(Error::Invalid(format!(
            "ratio plot: {} on {} is {}",
            b.pair, b.problem, b.ratio
        )));
    }
    render(&Bars { bars, title }, file, (1000, 520))
}

struct Bars<'a> {
    bars: &'a [Ratio],
    title: &'a str,
}

/// The distinct values of `f` over the bars, in their first order.
fn distinct<'a>(bars: &'a [Ratio], f: impl Fn(&'a Ratio) -> &'a str) -> Vec<&'a str> {
    let mut v: Vec<&str> = Vec::new();
    for b in bars {
        if !v.contains(&f(b)) {
            v.push(f(b));
        }
    }
    v
}

impl Draw for Bars<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String> {
        root.fill(&WHITE).map_err(text)?;
        let problems = distinct(self.bars, |b| &b.problem);
        let pairs = distinct(self.bars, |b| &b.pair);
        let x = (-0.5, problems.len() as f64 - 0.5);
        let y = log_range(self.bars.iter().map(|b| b.ratio).chain([0.5, 2.0]));
        let mut chart = ChartBuilder::on(root)
            .caption(self.title, (FONT, 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(x.0..x.1, (y.0..y.1).log_scale())
            .map_err(text)?;
        let names = problems.clone();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(problems.len())
            .x_label_formatter(&move |v| {
                let i = v.round();
                if (v - i).abs() < 1e-6 && i >= 0.0 {
                    names.get(i as usize).map_or(String::new(), |s| s.to_string())
                } else {
                    String::new()
                }
            })
            .y_desc("gharial time / peer time")
            .y_label_formatter(&|v| format!("{v}"))
            .label_style((FONT, 13))
            .draw()
            .map_err(text)?;
        let width = 0.8 / pairs.len() as f64;
        for (k, pair) in pairs.iter().enumerate() {
            let c = color(k);
            let rects: Vec<Rectangle<(f64, f64)>> = self
                .bars
                .iter()
                .filter(|b| b.pair == *pair)
                .map(|b| {
                    let i = problems.iter().position(|p| *p == b.problem).unwrap_or(0) as f64;
                    let left = i - 0.4 + k as f64 * width;
                    Rectangle::new([(left, y.0), (left + 0.9 * width, b.ratio)], c.filled())
                })
                .collect();
            chart
                .draw_series(rects)
                .map_err(text)?
                .label(*pair)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], c.filled()));
        }
        chart
            .draw_series(LineSeries::new([(x.0, 1.0), (x.1, 1.0)], BLACK.stroke_width(1)))
            .map_err(text)?;
        legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
        Ok(Figure {
            panels: vec![Panel {
                title: self.title.to_string(),
                x,
                y,
                log_y: true,
            }],
        })
    }
}
