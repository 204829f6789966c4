//! The inputs of the plots, from a [`Solution`] or from a solution file.

use std::path::Path;

use gharial::solvers::Solution;
use serde::Deserialize;

use crate::{Error, Result};

/// One solve's residuals per iteration: a pair of lines on a convergence plot.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Run {
    /// Legend label (the solver's name, say).
    pub label: String,
    /// Primal residual (dynamics and constraint violation) per iteration.
    pub prim_err: Vec<f64>,
    /// Dual residual (Lagrangian gradient) per iteration.
    pub dual_err: Vec<f64>,
    /// Augmented-Lagrangian (outer) iteration of each row; empty for solvers without one.
    pub al_iter: Vec<usize>,
    /// Penalty `mu` of each row; empty for solvers without one.
    pub mu: Vec<f64>,
}

impl Run {
    /// The history of `solution`, labelled `label`.
    pub fn from_solution(label: impl Into<String>, solution: &Solution) -> Self {
        let h = &solution.history;
        Self {
            label: label.into(),
            prim_err: h.iter().map(|r| r.prim_err).collect(),
            dual_err: h.iter().map(|r| r.dual_err).collect(),
            al_iter: h.iter().map(|r| r.al_iter).collect(),
            mu: h.iter().map(|r| r.mu).collect(),
        }
    }

    /// The rows of a solution file's history, labelled `label` (missing values are NaN,
    /// which the plot leaves out).
    pub fn from_history(label: impl Into<String>, rows: &[HistoryRow]) -> Self {
        let value = |v: Option<f64>| v.unwrap_or(f64::NAN);
        Self {
            label: label.into(),
            prim_err: rows.iter().map(|r| value(r.prim_err)).collect(),
            dual_err: rows.iter().map(|r| value(r.dual_err)).collect(),
            al_iter: rows.iter().map(|r| r.al_iter.unwrap_or(0)).collect(),
            mu: rows.iter().map(|r| value(r.mu)).collect(),
        }
    }
}

/// States and controls over time, with the controls' bounds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trajectory {
    /// Title of the figure (the problem's name, say).
    pub title: String,
    /// Time step (`None`: the axis counts nodes).
    pub dt: Option<f64>,
    /// States `x_0..x_N`.
    pub xs: Vec<Vec<f64>>,
    /// Controls `u_0..u_{N-1}`.
    pub us: Vec<Vec<f64>>,
    /// Lower bounds of the controls per stage (`-inf`: none); empty: not drawn.
    pub u_lower: Vec<Vec<f64>>,
    /// Upper bounds of the controls per stage (`+inf`: none); empty: not drawn.
    pub u_upper: Vec<Vec<f64>>,
}

/// One curve of a benchmark profile: the fraction of instances a solver solves within
/// each iteration budget.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ProfileCurve {
    /// Legend label (the solver's name).
    pub label: String,
    /// Iteration budgets, increasing.
    pub budget: Vec<f64>,
    /// Fraction of instances solved within each budget, in `[0, 1]`.
    pub solved: Vec<f64>,
}

/// One row of the iteration history of a solution file (absent or `null` values are
/// `None`: JSON writes non-finite numbers as `null`).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(default)]
pub struct HistoryRow {
    /// Primal residual.
    pub prim_err: Option<f64>,
    /// Dual residual.
    pub dual_err: Option<f64>,
    /// Augmented-Lagrangian iteration.
    pub al_iter: Option<usize>,
    /// Penalty.
    pub mu: Option<f64>,
    /// Cost.
    pub cost: Option<f64>,
}

/// The JSON document of `gharial solve --output` (the fields the plots use).
#[derive(Debug, Clone, Deserialize)]
pub struct SolutionFile {
    /// Catalogue name of the problem.
    pub problem: String,
    /// Solver name.
    pub solver: String,
    /// Time step.
    #[serde(default)]
    pub dt: Option<f64>,
    /// States.
    pub xs: Vec<Vec<f64>>,
    /// Controls.
    pub us: Vec<Vec<f64>>,
    /// Iteration history.
    #[serde(default)]
    pub history: Vec<HistoryRow>,
    /// Lower control bounds per stage (`null`: none), when the problem's constraints
    /// are control bounds.
    #[serde(default)]
    pub u_lower: Option<Vec<Vec<Option<f64>>>>,
    /// Upper control bounds per stage (`null`: none).
    #[serde(default)]
    pub u_upper: Option<Vec<Vec<Option<f64>>>>,
}

impl SolutionFile {
    /// Reads and parses `path`.
    ///
    /// # Errors
    /// If the file cannot be read or is not a solution document.
    pub fn read(path: &Path) -> Result<Self> {
        let err = |message: String| Error::Read {
            path: path.display().to_string(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
        serde_json::from_str(&text).map_err(|e| err(e.to_string()))
    }

    /// The residual history, labelled with the solver's name.
    pub fn run(&self) -> Run {
        Run::from_history(&self.solver, &self.history)
    }

    /// The trajectory with its control bounds.
    pub fn trajectory(&self) -> Trajectory {
        let bounds = |b: &Option<Vec<Vec<Option<f64>>>>, none: f64| -> Vec<Vec<f64>> {
            b.iter()
                .flatten()
                .map(|row| row.iter().map(|v| v.unwrap_or(none)).collect())
                .collect()
        };
        Trajectory {
            title: format!("{} ({})", self.problem, self.solver),
            dt: self.dt,
            xs: self.xs.clone(),
            us: self.us.clone(),
            u_lower: bounds(&self.u_lower, f64::NEG_INFINITY),
            u_upper: bounds(&self.u_upper, f64::INFINITY),
        }
    }
}
