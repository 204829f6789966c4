//! States and controls over time, the controls with their bounds.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::figure::{
    Draw, FONT, Figure, LinearChart, Panel, check_finite, color, dashed_key, finite_runs, legend, line, linear_chart,
    linear_range, render, text, titled,
};
use crate::{Error, Result, Trajectory};

/// Legend entries beyond this many series are left out (the lines are still drawn).
const MAX_LEGEND: usize = 12;

/// Draws the states (top) and the controls (bottom, piecewise constant over each step,
/// with their finite bounds dashed in the control's colour) against time, or against
/// the node index without a time step. Writes `path` (`.png` or `.svg`).
///
/// # Errors
/// No states, controls not one fewer than states, non-finite values, bounds of another
/// shape than the controls, or a file that cannot be written.
pub fn trajectory(traj: &Trajectory, path: &Path) -> Result<Figure> {
    let invalid = |m: String| Err(Error::Invalid(format!("trajectory plot: {m}")));
    if traj.xs.is_empty() {
        return invalid("no states".into());
    }
    if traj.us.len() + 1 != traj.xs.len() {
        return invalid(format!(
            "{} states need {} controls, got {}",
            traj.xs.len(),
            traj.xs.len() - 1,
            traj.us.len()
        ));
    }
    check_finite("xs", &traj.xs)?;
    check_finite("us", &traj.us)?;
    for (name, b) in [("u_lower", &traj.u_lower), ("u_upper", &traj.u_upper)] {
        let shape_ok = b.len() == traj.us.len() && b.iter().zip(&traj.us).all(|(l, u)| l.len() == u.len());
        if !b.is_empty() && !shape_ok {
            return invalid(format!("{name} does not have the shape of the controls"));
        }
    }
    if let Some(dt) = traj.dt
        && !(dt.is_finite() && dt > 0.0)
    {
        return invalid(format!("time step {dt} is not positive"));
    }
    render(&Plot(traj), path, (900, 720))
}

struct Plot<'a>(&'a Trajectory);

impl Plot<'_> {
    fn time(&self, k: usize) -> f64 {
        k as f64 * self.0.dt.unwrap_or(1.0)
    }

    /// A tick label of the time axis spanning `span`: whole nodes without a time step,
    /// else the decimals that a tenth of the span needs.
    fn tick(&self, v: f64, span: f64) -> String {
        let decimals = if self.0.dt.is_some() {
            (-(span / 10.0).log10().floor()).max(0.0) as usize
        } else {
            0
        };
        format!("{v:.decimals$}")
    }

    fn x_desc(&self) -> &'static str {
        if self.0.dt.is_some() { "time (s)" } else { "node" }
    }
}

/// Piecewise-constant steps of `values[t][i]` over `[time(t), time(t + 1)]`.
fn steps(values: &[Vec<f64>], i: usize, time: impl Fn(usize) -> f64) -> Vec<(f64, f64)> {
    let mut pts = Vec::with_capacity(2 * values.len());
    for (t, v) in values.iter().enumerate() {
        pts.push((time(t), v[i]));
        pts.push((time(t + 1), v[i]));
    }
    pts
}

impl Plot<'_> {
    /// A panel over the time axis `x` with its mesh drawn.
    fn panel<'a, DB: DrawingBackend>(
        &self,
        area: &'a DrawingArea<DB, Shift>,
        caption: &str,
        x: (f64, f64),
        y: (f64, f64),
    ) -> std::result::Result<LinearChart<'a, DB>, String> {
        let mut chart = linear_chart(area, caption, x, y, 64)?;
        chart
            .configure_mesh()
            .x_desc(self.x_desc())
            .x_label_formatter(&|v| self.tick(*v, x.1 - x.0))
            .label_style((FONT, 13))
            .draw()
            .map_err(text)?;
        Ok(chart)
    }

    /// The states, one line each.
    fn states<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: (f64, f64),
    ) -> std::result::Result<Panel, String> {
        let xs = &self.0.xs;
        let y = linear_range(xs.iter().flatten().copied());
        let mut chart = self.panel(area, "states", x, y)?;
        for i in 0..xs[0].len() {
            let pts = xs.iter().enumerate().map(|(t, v)| (self.time(t), v[i])).collect();
            line(&mut chart, pts, color(i), (i < MAX_LEGEND).then(|| format!("x[{i}]")))?;
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
        Ok(Panel {
            title: "states".into(),
            x,
            y,
            log_y: false,
        })
    }

    /// The controls as steps, over their finite bounds, dashed in the same colours.
    fn controls<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: (f64, f64),
    ) -> std::result::Result<Panel, String> {
        let traj = self.0;
        let bounds = [&traj.u_lower, &traj.u_upper];
        let finite_bounds = bounds.iter().copied().flatten().flatten().copied();
        let y = linear_range(traj.us.iter().flatten().copied().chain(finite_bounds));
        let mut chart = self.panel(area, "controls", x, y)?;
        let nu = traj.us.first().map_or(0, Vec::len);
        // Bounds first, so that a control on its bound is drawn over it.
        for i in 0..nu {
            for bound in bounds.iter().filter(|b| !b.is_empty()) {
                for seg in finite_runs(steps(bound, i, |t| self.time(t))) {
                    chart
                        .draw_series(DashedLineSeries::new(seg, 8, 5, color(i).stroke_width(2)))
                        .map_err(text)?;
                }
            }
        }
        for i in 0..nu {
            let pts = steps(&traj.us, i, |t| self.time(t));
            line(&mut chart, pts, color(i), (i < MAX_LEGEND).then(|| format!("u[{i}]")))?;
        }
        if bounds.iter().copied().flatten().flatten().any(|v| v.is_finite()) {
            dashed_key(&mut chart, BLACK, "bounds".into())?;
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
        Ok(Panel {
            title: "controls".into(),
            x,
            y,
            log_y: false,
        })
    }
}

impl Draw for Plot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String> {
        let body = titled(root, &self.0.title)?;
        let areas = body.split_evenly((2, 1));
        let x = (0.0, self.time(self.0.xs.len() - 1).max(f64::MIN_POSITIVE));
        Ok(Figure {
            panels: vec![self.states(&areas[0], x)?, self.controls(&areas[1], x)?],
        })
    }
}
