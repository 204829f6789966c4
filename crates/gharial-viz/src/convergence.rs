//! Residuals per iteration, several solves on one log-scale plot.

use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::figure::{Draw, FONT, Figure, Panel, color, dashed_key, finite_runs, legend, line, log_range, render, text};
use crate::{Error, Result, Run};

/// Draws the primal (solid) and dual (dashed) residuals of each run per iteration on a
/// log scale, with a dotted vertical line where an augmented-Lagrangian (outer)
/// iteration begins, labelled with its penalty `mu`. Writes `path` (`.png` or `.svg`).
///
/// # Errors
/// No runs, a run without rows or with primal and dual histories of different lengths,
/// or a file that cannot be written.
pub fn convergence(runs: &[Run], title: &str, path: &Path) -> Result<Figure> {
    if runs.is_empty() {
        return Err(Error::Invalid("convergence plot: no runs".into()));
    }
    for r in runs {
        if r.prim_err.is_empty() || r.prim_err.len() != r.dual_err.len() {
            return Err(Error::Invalid(format!(
                "convergence plot: run `{}` has {} primal and {} dual residuals (need the same, at least one)",
                r.label,
                r.prim_err.len(),
                r.dual_err.len()
            )));
        }
    }
    render(&Convergence { runs, title }, path, (900, 560))
}

struct Convergence<'a> {
    runs: &'a [Run],
    title: &'a str,
}

/// The rows where an outer iteration begins (the penalty may change there).
fn outer_starts(run: &Run) -> Vec<usize> {
    (1..run.al_iter.len())
        .filter(|&k| run.al_iter[k] != run.al_iter[k - 1])
        .collect()
}

/// A chart with a linear horizontal and a logarithmic vertical axis.
type LogChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, LogCoord<f64>>>;

/// The residuals of one run: primal solid, dual dashed, in colour `c`. A log axis has no
/// zero: zeros (an exactly feasible point) are left out, and a primal residual that is
/// zero throughout (single shooting) gets a legend entry saying so.
fn draw_residuals<'a, DB: DrawingBackend + 'a>(
    chart: &mut LogChart<'a, DB>,
    run: &Run,
    c: RGBColor,
) -> std::result::Result<(), String> {
    let points = |vals: &[f64]| -> Vec<(f64, f64)> {
        let at = |v: f64| if v > 0.0 { v } else { f64::NAN };
        vals.iter().enumerate().map(|(k, &v)| (k as f64, at(v))).collect()
    };
    if run.prim_err.iter().all(|&v| v == 0.0) {
        line(chart, Vec::new(), c, Some(format!("{} primal = 0", run.label)))?;
    }
    for (j, seg) in finite_runs(points(&run.prim_err)).into_iter().enumerate() {
        line(chart, seg, c, (j == 0).then(|| format!("{} primal", run.label)))?;
    }
    let dual = finite_runs(points(&run.dual_err));
    if !dual.is_empty() {
        dashed_key(chart, c, format!("{} dual", run.label))?;
    }
    for seg in dual {
        chart
            .draw_series(DashedLineSeries::new(seg, 7, 5, c.stroke_width(2)))
            .map_err(text)?;
    }
    Ok(())
}

/// A dotted vertical line where each outer iteration of run `i` begins, labelled with
/// its penalty `μ` (right of the line, or left of it near the right edge; the runs'
/// labels at different heights).
fn mark_outer_iterations<'a, DB: DrawingBackend + 'a>(
    chart: &mut LogChart<'a, DB>,
    run: &Run,
    i: usize,
    (x, y): ((f64, f64), (f64, f64)),
) -> std::result::Result<(), String> {
    let c = color(i);
    for k in outer_starts(run) {
        let kx = k as f64;
        chart
            .draw_series(DashedLineSeries::new(
                [(kx, y.0), (kx, y.1)],
                2,
                4,
                c.mix(0.5).stroke_width(1),
            ))
            .map_err(text)?;
        if let Some(mu) = run.mu.get(k).filter(|m| m.is_finite()) {
            let shift = 0.01 * (x.1 - x.0);
            let label_x = if kx > x.0 + 0.85 * (x.1 - x.0) {
                kx - 9.0 * shift
            } else {
                kx + shift
            };
            let label_y = y.1 / 10f64.powf(0.25 + 0.35 * i as f64);
            let font = (FONT, 12).into_font().color(&c);
            chart
                .draw_series([Text::new(format!("μ={mu:.0e}"), (label_x, label_y), font)])
                .map_err(text)?;
        }
    }
    Ok(())
}

impl Draw for Convergence<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String> {
        root.fill(&WHITE).map_err(text)?;
        let rows = self.runs.iter().map(|r| r.prim_err.len()).max().unwrap_or(1);
        let x = (0.0, (rows.max(2) - 1) as f64);
        let residuals = self.runs.iter().flat_map(|r| r.prim_err.iter().chain(&r.dual_err));
        let y = log_range(residuals.copied());
        let mut chart = ChartBuilder::on(root)
            .caption(self.title, (FONT, 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(72)
            .build_cartesian_2d(x.0..x.1, (y.0..y.1).log_scale())
            .map_err(text)?;
        chart
            .configure_mesh()
            .x_desc("iteration")
            .y_desc("residual")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .label_style((FONT, 14))
            .draw()
            .map_err(text)?;
        for (i, run) in self.runs.iter().enumerate() {
            draw_residuals(&mut chart, run, color(i))?;
            mark_outer_iterations(&mut chart, run, i, (x, y))?;
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight, 14)?;
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
