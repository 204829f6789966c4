//! The options of any solver of the library, chosen by name ([`SolverOptions`]).

use super::Solver;
use super::altro::{Altro, AltroOptions};
use super::bcl_ddp::{BclDdp, BclDdpOptions};
use super::csqp::{Csqp, CsqpOptions};
use super::ddp::{Ddp, DdpOptions, DdpVariant};
use super::log::LogSink;
use super::proxddp::{ProxDdp, ProxDdpOptions};
use crate::error::{Error, Result};
use crate::nlp::{ProxNlpOcp, ProxNlpOptions};

/// The options of one solver, so that the command-line tool, the benchmarks, the
/// catalogue and the Python package pick a solver by name and build it the same way.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum SolverOptions {
    /// ProxDDP (Jallet et al. 2023).
    ProxDdp(ProxDdpOptions),
    /// The DDP family and stagewise SQP (Tassa et al. 2012, Mastalli et al. 2020,
    /// Jordana et al. 2023); the member is [`DdpOptions::variant`].
    Ddp(DdpOptions),
    /// CSQP (Jordana et al. 2023).
    Csqp(CsqpOptions),
    /// BCL-DDP (El Kazdadi et al. 2021): equality constraints only.
    BclDdp(BclDdpOptions),
    /// ALTRO's AL-iLQR (Howell et al. 2019).
    Altro(AltroOptions),
    /// ProxNLP on the whole problem with a dense KKT system ([`crate::nlp`]): small
    /// problems only (at most [`crate::nlp::MAX_KKT_DIM`] rows, refused at `setup`).
    ProxNlp(ProxNlpOptions),
}

/// The solver names, in the order of [`SolverOptions::names`].
const NAMES: [&str; 10] = [
    "proxddp", "ddp", "fddp", "box-ddp", "box-fddp", "sqp", "csqp", "bcl-ddp", "altro", "proxnlp",
];

impl SolverOptions {
    /// Every solver name: `proxddp`, `ddp`, `fddp`, `box-ddp`, `box-fddp`, `sqp`, `csqp`,
    /// `bcl-ddp`, `altro`, `proxnlp`.
    pub fn names() -> &'static [&'static str] {
        &NAMES
    }

    /// The default options of the solver `name` (one of [`SolverOptions::names`]).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] for an unknown name, listing the valid ones.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "proxddp" => Ok(SolverOptions::ProxDdp(ProxDdpOptions::default())),
            "csqp" => Ok(SolverOptions::Csqp(CsqpOptions::default())),
            "bcl-ddp" => Ok(SolverOptions::BclDdp(BclDdpOptions::default())),
            "altro" => Ok(SolverOptions::Altro(AltroOptions::default())),
            "proxnlp" => Ok(SolverOptions::ProxNlp(ProxNlpOptions::default())),
            _ => DdpVariant::from_name(name)
                .map(|v| SolverOptions::Ddp(DdpOptions::new(v)))
                .ok_or_else(|| {
                    Error::option(
                        "solver",
                        format!("unknown solver `{name}` (one of {})", NAMES.join(", ")),
                    )
                }),
        }
    }

    /// The solver's name (see [`SolverOptions::names`]).
    pub fn name(&self) -> &'static str {
        match self {
            SolverOptions::ProxDdp(_) => "proxddp",
            SolverOptions::Ddp(o) => o.variant.name(),
            SolverOptions::Csqp(_) => "csqp",
            SolverOptions::BclDdp(_) => "bcl-ddp",
            SolverOptions::Altro(_) => "altro",
            SolverOptions::ProxNlp(_) => "proxnlp",
        }
    }

    /// Sends the solver's iteration log to `log`.
    pub fn set_log(&mut self, log: LogSink) {
        match self {
            SolverOptions::ProxDdp(o) => o.log = log,
            SolverOptions::Ddp(o) => o.log = log,
            SolverOptions::Csqp(o) => o.log = log,
            SolverOptions::BclDdp(o) => o.log = log,
            SolverOptions::Altro(o) => o.log = log,
            SolverOptions::ProxNlp(o) => o.log = log,
        }
    }

    /// Checks every option's range (the solver's own validation).
    ///
    /// # Errors
    /// Names the offending option and its valid range.
    pub fn validate(&self) -> Result<()> {
        match self {
            SolverOptions::ProxDdp(o) => o.validate(),
            SolverOptions::Ddp(o) => o.validate(),
            SolverOptions::Csqp(o) => o.validate(),
            SolverOptions::BclDdp(o) => o.validate(),
            SolverOptions::Altro(o) => o.validate(),
            SolverOptions::ProxNlp(o) => o.validate(),
        }
    }

    /// A new solver with these options (not set up).
    pub fn build(&self) -> Box<dyn Solver> {
        match self {
            SolverOptions::ProxDdp(o) => Box::new(ProxDdp::new(o.clone())),
            SolverOptions::Ddp(o) => Box::new(Ddp::new(o.clone())),
            SolverOptions::Csqp(o) => Box::new(Csqp::new(o.clone())),
            SolverOptions::BclDdp(o) => Box::new(BclDdp::new(o.clone())),
            SolverOptions::Altro(o) => Box::new(Altro::new(o.clone())),
            SolverOptions::ProxNlp(o) => Box::new(ProxNlpOcp::new(o.clone())),
        }
    }
}
