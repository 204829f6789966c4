//! Benchmark profiles: the fraction of instances solved against the iteration budget.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::figure::{Draw, FONT, Figure, Panel, color, legend, line, linear_range, render, text};
use crate::{Error, ProfileCurve, Result};

/// Draws one line per solver: the percentage of instances solved within each iteration
/// budget (the stagewise-SQP paper's Fig. 1). Writes `path` (`.png` or `.svg`).
///
/// # Errors
/// No curves, a curve whose budgets and fractions differ in length, are empty, are not
/// increasing, or whose fractions leave `[0, 1]`; a file that cannot be written.
pub fn profile(curves: &[ProfileCurve], title: &str, path: &Path) -> Result<Figure> {
    if curves.is_empty() {
        return Err(Error::Invalid("profile plot: no curves".into()));
    }
    for c in curves {
        let invalid = |m: &str| Err(Error::Invalid(format!("profile plot: curve `{}` {m}", c.label)));
        if c.budget.is_empty() || c.budget.len() != c.solved.len() {
            return invalid("needs as many fractions as budgets, at least one");
        }
        if !c.budget.iter().all(|b| b.is_finite()) || c.budget.windows(2).any(|w| w[1] <= w[0]) {
            return invalid("has budgets that are not finite and increasing");
        }
        if !c.solved.iter().all(|f| (0.0..=1.0).contains(f)) {
            return invalid("has fractions outside [0, 1]");
        }
    }
    render(&Profile { curves, title }, path, (900, 560))
}

struct Profile<'a> {
    curves: &'a [ProfileCurve],
    title: &'a str,
}

impl Draw for Profile<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String> {
        root.fill(&WHITE).map_err(text)?;
        let (lo, hi) = linear_range(self.curves.iter().flat_map(|c| c.budget.iter().copied()));
        let x = (lo.max(0.0), hi);
        let y = (0.0, 105.0);
        let mut chart = ChartBuilder::on(root)
            .caption(self.title, (FONT, 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .map_err(text)?;
        chart
            .configure_mesh()
            .x_desc("iteration budget")
            .y_desc("solved (%)")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .label_style((FONT, 14))
            .draw()
            .map_err(text)?;
        for (i, curve) in self.curves.iter().enumerate() {
            let c = color(i);
            // A staircase: the fraction holds until the next budget.
            let mut pts = Vec::with_capacity(2 * curve.budget.len());
            for (k, (&b, &f)) in curve.budget.iter().zip(&curve.solved).enumerate() {
                if k > 0 {
                    pts.push((b, 100.0 * curve.solved[k - 1]));
                }
                pts.push((b, 100.0 * f));
            }
            line(&mut chart, pts, c, Some(curve.label.clone()))?;
        }
        legend(&mut chart, SeriesLabelPosition::LowerRight, 14)?;
        Ok(Figure {
            panels: vec![Panel {
                title: self.title.to_string(),
                x,
                y,
                log_y: false,
            }],
        })
    }
}
