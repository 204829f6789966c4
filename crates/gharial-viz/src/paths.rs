//! Paths of points in 3D (an end effector, a base, the feet) in three projections, with
//! the targets and the vertical-cylinder obstacles of the problem.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::figure::{Draw, FONT, Figure, Panel, color, legend, line, linear_chart, linear_range, render, text, titled};
use crate::{Error, Result};

/// The path of one point, one position per node.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointPath {
    /// Legend label (the frame's name, say).
    pub label: String,
    /// Positions.
    pub points: Vec<[f64; 3]>,
}

/// A vertical cylinder, seen as a disc from above and as a band from the sides.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    /// Axis position `(x, y)`.
    pub centre: [f64; 2],
    /// Radius.
    pub radius: f64,
    /// Bottom and top heights.
    pub z: (f64, f64),
}

/// Draws the paths in the projections x-y (top view), x-z and y-z (side views), each
/// with equal scales on both axes, the start of each path as a dot, `targets` as crosses
/// and `cylinders` shaded. Writes `file` (`.png` or `.svg`).
///
/// # Errors
/// No paths, an empty path, non-finite positions, or a file that cannot be written.
pub fn paths(
    paths: &[PointPath],
    targets: &[[f64; 3]],
    cylinders: &[Cylinder],
    title: &str,
    file: &Path,
) -> Result<Figure> {
    if paths.is_empty() {
        return Err(Error::Invalid("path plot: no paths".into()));
    }
    for p in paths {
        if p.points.is_empty() {
            return Err(Error::Invalid(format!("path plot: path `{}` is empty", p.label)));
        }
        if let Some(k) = p.points.iter().position(|q| !q.iter().all(|v| v.is_finite())) {
            return Err(Error::Invalid(format!(
                "path plot: path `{}` point {k} is not finite",
                p.label
            )));
        }
    }
    let plot = Paths {
        paths,
        targets,
        cylinders,
        title,
    };
    render(&plot, file, (1200, 440))
}

struct Paths<'a> {
    paths: &'a [PointPath],
    targets: &'a [[f64; 3]],
    cylinders: &'a [Cylinder],
    title: &'a str,
}

/// Equal-scale ranges around the values of two coordinates.
fn square_ranges(a: Vec<f64>, b: Vec<f64>) -> ((f64, f64), (f64, f64)) {
    let (ra, rb) = (linear_range(a), linear_range(b));
    let half = 0.5 * (ra.1 - ra.0).max(rb.1 - rb.0);
    let centred = |r: (f64, f64)| {
        let c = 0.5 * (r.0 + r.1);
        (c - half, c + half)
    };
    (centred(ra), centred(rb))
}

impl Draw for Paths<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<Figure, String> {
        let body = titled(root, self.title)?;
        let areas = body.split_evenly((1, 3));
        let mut panels = Vec::new();
        for (area, (i, j), name) in [
            (&areas[0], (0, 1), "x-y (top)"),
            (&areas[1], (0, 2), "x-z (side)"),
            (&areas[2], (1, 2), "y-z (side)"),
        ] {
            let axis = ["x", "y", "z"];
            // The cylinders' extents in this projection, so that they fit.
            let extents = |k: usize| -> Vec<f64> {
                self.cylinders
                    .iter()
                    .flat_map(|c| match k {
                        2 => vec![c.z.0, c.z.1],
                        _ => vec![c.centre[k] - c.radius, c.centre[k] + c.radius],
                    })
                    .collect()
            };
            let coords = |k: usize| -> Vec<f64> {
                let pts = self.paths.iter().flat_map(|p| p.points.iter().map(move |q| q[k]));
                pts.chain(self.targets.iter().map(|t| t[k])).chain(extents(k)).collect()
            };
            let (x, y) = square_ranges(coords(i), coords(j));
            let mut chart = linear_chart(area, name, x, y, 52)?;
            chart
                .configure_mesh()
                .x_desc(axis[i])
                .y_desc(axis[j])
                .label_style((FONT, 12))
                .draw()
                .map_err(text)?;
            let shade = RGBColor(200, 60, 60).mix(0.3);
            for c in self.cylinders {
                if j == 1 {
                    let disc: Vec<(f64, f64)> = (0..=48)
                        .map(|k| {
                            let a = std::f64::consts::TAU * f64::from(k) / 48.0;
                            (c.centre[0] + c.radius * a.cos(), c.centre[1] + c.radius * a.sin())
                        })
                        .collect();
                    chart.draw_series([Polygon::new(disc, shade.filled())]).map_err(text)?;
                } else {
                    let (lo, hi) = (c.centre[i] - c.radius, c.centre[i] + c.radius);
                    chart
                        .draw_series([Rectangle::new([(lo, c.z.0), (hi, c.z.1)], shade.filled())])
                        .map_err(text)?;
                }
            }
            for (k, p) in self.paths.iter().enumerate() {
                let c = color(k);
                let pts: Vec<(f64, f64)> = p.points.iter().map(|q| (q[i], q[j])).collect();
                let start = pts[0];
                line(&mut chart, pts, c, Some(p.label.clone()))?;
                chart.draw_series([Circle::new(start, 4, c.filled())]).map_err(text)?;
            }
            for t in self.targets {
                chart
                    .draw_series([Cross::new((t[i], t[j]), 7, RGBColor(20, 150, 40).stroke_width(3))])
                    .map_err(text)?;
            }
            if i == 0 && j == 1 {
                legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
            }
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

/// The paths of the frames named `frames` of `model` along the configurations `qs`
/// (forward kinematics), labelled with the frames' names.
///
/// # Errors
/// An unknown frame or a configuration that does not fit the model.
pub fn frame_paths(model: &gharial_multibody::Model, qs: &[Vec<f64>], frames: &[&str]) -> Result<Vec<PointPath>> {
    use gharial_multibody::{Data, forward_kinematics_placements, update_frame_placements};
    let ids: Vec<usize> = frames
        .iter()
        .map(|f| model.frame_id(f).map_err(|e| Error::Invalid(format!("path plot: {e}"))))
        .collect::<Result<_>>()?;
    let mut data = Data::new(model);
    let mut out: Vec<PointPath> = frames
        .iter()
        .map(|f| PointPath {
            label: (*f).to_string(),
            points: Vec::with_capacity(qs.len()),
        })
        .collect();
    for (t, q) in qs.iter().enumerate() {
        forward_kinematics_placements(model, &mut data, q)
            .map_err(|e| Error::Invalid(format!("path plot: configuration {t}: {e}")))?;
        update_frame_placements(model, &mut data).map_err(|e| Error::Invalid(e.to_string()))?;
        for (path, &id) in out.iter_mut().zip(&ids) {
            let m = data.frame_placement(id);
            path.points.push([m.translation.x, m.translation.y, m.translation.z]);
        }
    }
    Ok(out)
}
