//! Pictures of gharial solves.
//!
//! - [`convergence`]: primal and dual residuals per iteration on a log scale, the
//!   augmented-Lagrangian (outer) iterations marked with their penalty `mu`, several
//!   solves on one plot (the ProxDDP paper's convergence figures).
//! - [`trajectory`]: states and controls over time, the controls with their bounds (the
//!   ProxDDP paper's Figs. 4-11), as piecewise-constant steps.
//! - [`paths`]: points (an end effector, a base, the feet) in three projections, with
//!   targets and obstacles; [`frame_paths`] computes them for a robot.
//! - [`forces`]: contact forces over time, with their friction-cone ratios.
//! - [`profile`]: the fraction of instances solved against the iteration budget (the
//!   stagewise-SQP paper's Fig. 1); [`ratios`]: gharial's solve times over the peers'
//!   from one run of the peer harness ([`ratios_from_harness`]).
//!
//! - [`viewer`]: the 3D trajectory viewer, one self-contained HTML page.
//!
//! Each plot is written as PNG or SVG, chosen by the file's extension, with an embedded
//! font (no system font needed), and returns the [`Figure`] it drew: the axis ranges of
//! each panel. The inputs are plain data ([`Run`], [`Trajectory`], [`ProfileCurve`]),
//! built from a [`gharial::solvers::Solution`] or read from the JSON file that
//! `gharial solve --output` writes ([`SolutionFile`]).

mod convergence;
mod data;
mod figure;
mod forces;
mod paths;
mod profile;
mod ratios;
mod trajectory;
pub mod viewer;

pub use convergence::convergence;
pub use data::{HistoryRow, ProfileCurve, Run, SolutionFile, Trajectory};
pub use figure::{Figure, Panel};
pub use forces::{FootForces, forces};
pub use paths::{Cylinder, PointPath, frame_paths, paths};
pub use profile::profile;
pub use ratios::{Ratio, ratios, ratios_from_harness};
pub use trajectory::trajectory;

/// What can go wrong when drawing.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The file name has no extension this crate writes.
    #[error("cannot write `{0}`: the file name must end in .png or .svg")]
    Format(String),
    /// Inputs that cannot be drawn (empty, non-finite, mismatched sizes).
    #[error("{0}")]
    Invalid(String),
    /// An error of the drawing backend (file system, encoder).
    #[error("drawing `{path}`: {message}")]
    Backend {
        /// The file being drawn.
        path: String,
        /// The backend's message.
        message: String,
    },
    /// A solution file that cannot be read.
    #[error("reading `{path}`: {message}")]
    Read {
        /// The file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
}

/// The result type of this crate.
pub type Result<T> = std::result::Result<T, Error>;
