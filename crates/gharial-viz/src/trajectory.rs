//! States and controls over time, the controls with their bounds.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::figure::{Draw, FONT, Figure, Panel, check_finite, color, finite_runs, legend, linear_range, render, text};
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

impl Draw for Plot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String> {
        let traj = self.0;
        root.fill(&WHITE).map_err(text)?;
        let title_height = 34;
        let (top, body) = root.split_vertically(title_height);
        top.titled(&traj.title, (FONT, 22)).map_err(text)?;
        let areas = body.split_evenly((2, 1));
        let x = (0.0, self.time(traj.xs.len() - 1).max(f64::MIN_POSITIVE));
        let mut panels = Vec::new();

        // States.
        let y = linear_range(traj.xs.iter().flatten().copied());
        let mut chart = ChartBuilder::on(&areas[0])
            .caption("states", (FONT, 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .map_err(text)?;
        chart
            .configure_mesh()
            .x_desc(self.x_desc())
            .x_label_formatter(&|v| self.tick(*v, x.1 - x.0))
            .label_style((FONT, 13))
            .draw()
            .map_err(text)?;
        let nx = traj.xs[0].len();
        for i in 0..nx {
            let c = color(i);
            let pts: Vec<_> = traj.xs.iter().enumerate().map(|(t, v)| (self.time(t), v[i])).collect();
            let s = chart
                .draw_series(LineSeries::new(pts, c.stroke_width(2)))
                .map_err(text)?;
            if i < MAX_LEGEND {
                s.label(format!("x[{i}]"))
                    .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(2)));
            }
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
        panels.push(Panel {
            title: "states".into(),
            x,
            y,
            log_y: false,
        });

        // Controls and their bounds.
        let finite_bounds = traj.u_lower.iter().chain(&traj.u_upper).flatten().copied();
        let y = linear_range(traj.us.iter().flatten().copied().chain(finite_bounds));
        let mut chart = ChartBuilder::on(&areas[1])
            .caption("controls", (FONT, 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .map_err(text)?;
        chart
            .configure_mesh()
            .x_desc(self.x_desc())
            .x_label_formatter(&|v| self.tick(*v, x.1 - x.0))
            .label_style((FONT, 13))
            .draw()
            .map_err(text)?;
        let nu = traj.us.first().map_or(0, Vec::len);
        // Bounds first, so that a control on its bound is drawn over it.
        for i in 0..nu {
            for bound in [&traj.u_lower, &traj.u_upper] {
                if bound.is_empty() {
                    continue;
                }
                for seg in finite_runs(steps(bound, i, |t| self.time(t))) {
                    chart
                        .draw_series(DashedLineSeries::new(seg, 8, 5, color(i).stroke_width(2)))
                        .map_err(text)?;
                }
            }
        }
        for i in 0..nu {
            let c = color(i);
            let s = chart
                .draw_series(LineSeries::new(steps(&traj.us, i, |t| self.time(t)), c.stroke_width(2)))
                .map_err(text)?;
            if i < MAX_LEGEND {
                s.label(format!("u[{i}]"))
                    .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(2)));
            }
        }
        let bounded = traj
            .u_lower
            .iter()
            .chain(&traj.u_upper)
            .flatten()
            .any(|v| v.is_finite());
        if bounded {
            // A legend entry for the dashed bounds.
            chart
                .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
                .map_err(text)?
                .label("bounds")
                .legend(|(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new([(0, 0), (8, 0)], BLACK.stroke_width(2))
                        + PathElement::new([(13, 0), (20, 0)], BLACK.stroke_width(2))
                });
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
        panels.push(Panel {
            title: "controls".into(),
            x,
            y,
            log_y: false,
        });
        Ok(Figure { panels })
    }
}
