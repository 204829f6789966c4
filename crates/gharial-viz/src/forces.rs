//! Contact forces over time: the normal force of each foot and, with a friction
//! coefficient, its friction-cone ratio `|f_t| / (μ f_n)` (1 on the cone's edge).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::figure::{
    Draw, FONT, Figure, Panel, color, finite_runs, legend, line, linear_chart, linear_range, render, text, titled,
};
use crate::{Error, Result};

/// The contact force of one foot at every stage (N, world axes; zero in the air).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FootForces {
    /// Legend label (the foot's frame).
    pub label: String,
    /// Forces per stage.
    pub forces: Vec<[f64; 3]>,
}

/// Draws the normal forces `f_z` of the feet (top) and, when `mu` is given, their
/// friction-cone ratios `|(f_x, f_y)| / (μ f_z)` where the foot pushes (bottom, the
/// cone's edge dashed at 1), against time (`dt`) or the stage index. Writes `file`.
///
/// # Errors
/// No feet, feet with different numbers of stages or none, non-finite forces, a friction
/// coefficient that is not positive, or a file that cannot be written.
pub fn forces(feet: &[FootForces], dt: Option<f64>, mu: Option<f64>, title: &str, file: &Path) -> Result<Figure> {
    let invalid = |m: String| Err(Error::Invalid(format!("force plot: {m}")));
    let Some(first) = feet.first() else {
        return invalid("no feet".into());
    };
    if first.forces.is_empty() || feet.iter().any(|f| f.forces.len() != first.forces.len()) {
        return invalid("every foot needs the same, non-zero number of stages".into());
    }
    if let Some(f) = feet.iter().find(|f| f.forces.iter().flatten().any(|v| !v.is_finite())) {
        return invalid(format!("foot `{}` has non-finite forces", f.label));
    }
    if let Some(m) = mu
        && !(m.is_finite() && m > 0.0)
    {
        return invalid(format!("friction coefficient {m} is not positive"));
    }
    let panels = if mu.is_some() { 2 } else { 1 };
    render(&Plot { feet, dt, mu, title }, file, (900, 300 + 260 * panels))
}

struct Plot<'a> {
    feet: &'a [FootForces],
    dt: Option<f64>,
    mu: Option<f64>,
    title: &'a str,
}

/// A panel's title, its lines (one per foot) and its vertical range.
type Series = (&'static str, Vec<Vec<(f64, f64)>>, (f64, f64));

/// The cone ratio of a force, `NaN` where the foot does not push.
fn cone_ratio(f: &[f64; 3], mu: f64) -> f64 {
    if f[2] > 1e-9 {
        f[0].hypot(f[1]) / (mu * f[2])
    } else {
        f64::NAN
    }
}

impl Draw for Plot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String> {
        let body = titled(root, self.title)?;
        let areas = body.split_evenly((if self.mu.is_some() { 2 } else { 1 }, 1));
        let time = |t: usize| t as f64 * self.dt.unwrap_or(1.0);
        let stages = self.feet[0].forces.len();
        let x = (0.0, time(stages.max(2) - 1));
        let x_desc = if self.dt.is_some() { "time (s)" } else { "stage" };
        let mut series: Vec<Series> = Vec::new();
        let normal: Vec<Vec<(f64, f64)>> = self
            .feet
            .iter()
            .map(|f| f.forces.iter().enumerate().map(|(t, v)| (time(t), v[2])).collect())
            .collect();
        let y = linear_range(normal.iter().flatten().map(|p| p.1));
        series.push(("normal force f_z (N)", normal, y));
        if let Some(mu) = self.mu {
            let ratios: Vec<Vec<(f64, f64)>> = self
                .feet
                .iter()
                .map(|f| {
                    f.forces
                        .iter()
                        .enumerate()
                        .map(|(t, v)| (time(t), cone_ratio(v, mu)))
                        .collect()
                })
                .collect();
            let y = linear_range(ratios.iter().flatten().map(|p| p.1).chain([0.0, 1.0]));
            series.push(("friction-cone ratio |f_t| / (μ f_z)", ratios, y));
        }
        let mut panels = Vec::new();
        for (area, (name, lines, y)) in areas.iter().zip(series) {
            let mut chart = linear_chart(area, name, x, y, 60)?;
            chart
                .configure_mesh()
                .x_desc(x_desc)
                .label_style((FONT, 13))
                .draw()
                .map_err(text)?;
            for (k, (foot, pts)) in self.feet.iter().zip(lines).enumerate() {
                for (j, seg) in finite_runs(pts).into_iter().enumerate() {
                    line(&mut chart, seg, color(k), (j == 0).then(|| foot.label.clone()))?;
                }
            }
            if panels.len() == 1 {
                chart
                    .draw_series(DashedLineSeries::new(
                        [(x.0, 1.0), (x.1, 1.0)],
                        8,
                        5,
                        BLACK.stroke_width(1),
                    ))
                    .map_err(text)?;
            }
            legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
            panels.push(Panel {
                title: name.to_string(),
                x,
                y,
                log_y: false,
            });
        }
        Ok(Figure { panels })
    }
}
