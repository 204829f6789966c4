//! Backtracking line searches shared by the solvers.
//!
//! The Armijo search accepts a step length `α` when
//! `φ(α) ≤ φ_ref + c1 α φ'(0)` (ProxDDP (18)), with `φ_ref = φ(0)` (monotone) or the
//! Zhang-Hager average of past merit values (nonmonotone). Trial steps come from a
//! safeguarded quadratic, then cubic, interpolation of the values seen so far
//! (Nocedal & Wright, section 3.5), kept within `[c_min α, c_max α]` of the last trial.

/// How trial step lengths are chosen after a rejected trial.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Quadratic then cubic interpolation, safeguarded.
    #[default]
    Cubic,
    /// Multiply by `contraction_max`.
    Bisection,
}

/// Options of the backtracking line search.
#[derive(Debug, Clone, Copy)]
pub struct LinesearchOptions {
    /// Sufficient-decrease constant `c1` (default `1e-4`).
    pub c1: f64,
    /// Smallest step length tried before giving up (default `1e-10`).
    pub alpha_min: f64,
    /// Largest number of trials (default 40).
    pub max_trials: usize,
    /// Lower safeguard on the contraction of `α` per trial (default 0.1).
    pub contraction_min: f64,
    /// Upper safeguard on the contraction of `α` per trial (default 0.5).
    pub contraction_max: f64,
    /// Interpolation rule (default cubic).
    pub interpolation: Interpolation,
}

impl Default for LinesearchOptions {
    fn default() -> Self {
        Self {
            c1: 1e-4,
            alpha_min: 1e-10,
            max_trials: 40,
            contraction_min: 0.1,
            contraction_max: 0.5,
            interpolation: Interpolation::Cubic,
        }
    }
}

impl LinesearchOptions {
    /// Checks the ranges of the options.
    ///
    /// # Errors
    /// Names the offending option.
    pub fn validate(&self) -> crate::Result<()> {
        use crate::Error;
        if !(self.c1 > 0.0 && self.c1 < 0.5) {
            return Err(Error::option("linesearch.c1", "must be in (0, 0.5)"));
        }
        if !(self.alpha_min > 0.0 && self.alpha_min < 1.0) {
            return Err(Error::option("linesearch.alpha_min", "must be in (0, 1)"));
        }
        if self.max_trials == 0 {
            return Err(Error::option("linesearch.max_trials", "must be at least 1"));
        }
        if !(0.0 < self.contraction_min && self.contraction_min <= self.contraction_max && self.contraction_max < 1.0) {
            return Err(Error::option(
                "linesearch.contraction_min/max",
                "need 0 < contraction_min <= contraction_max < 1",
            ));
        }
        Ok(())
    }
}

/// Outcome of a line search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinesearchResult {
    /// Last step length tried (the accepted one if `accepted`).
    pub alpha: f64,
    /// Merit value at `alpha`.
    pub phi: f64,
    /// Whether the sufficient-decrease condition holds at `alpha`.
    pub accepted: bool,
    /// Number of merit evaluations.
    pub trials: usize,
}

/// Next trial step from the values seen so far (safeguarded interpolation).
fn next_alpha(opts: &LinesearchOptions, phi0: f64, dphi0: f64, cur: (f64, f64), prev: Option<(f64, f64)>) -> f64 {
    let (a1, p1) = cur;
    let lo = opts.contraction_min * a1;
    let hi = opts.contraction_max * a1;
    if opts.interpolation == Interpolation::Bisection || !p1.is_finite() {
        return hi;
    }
    let cand = match prev {
        // Minimiser of the quadratic through φ(0), φ'(0), φ(α1).
        None => -dphi0 * a1 * a1 / (2.0 * (p1 - phi0 - dphi0 * a1)),
        // Minimiser of the cubic through φ(0), φ'(0), φ(α0), φ(α1).
        Some((a0, p0)) if p0.is_finite() => {
            let r1 = p1 - phi0 - dphi0 * a1;
            let r0 = p0 - phi0 - dphi0 * a0;
            let den = a0 * a0 * a1 * a1 * (a1 - a0);
            let a = (a0 * a0 * r1 - a1 * a1 * r0) / den;
            let b = (-a0 * a0 * a0 * r1 + a1 * a1 * a1 * r0) / den;
            if a.abs() < f64::EPSILON * b.abs().max(1.0) {
                -dphi0 / (2.0 * b)
            } else {
                let disc = b * b - 3.0 * a * dphi0;
                if disc < 0.0 {
                    f64::NAN
                } else {
                    (-b + disc.sqrt()) / (3.0 * a)
                }
            }
        }
        Some(_) => f64::NAN,
    };
    if cand.is_finite() { cand.clamp(lo, hi) } else { hi }
}

/// Backtracking Armijo line search: the full step `α = 1` first, then `alpha_model`
/// (the minimiser of a model of the merit function, when given and in `(0, 1)`), then
/// safeguarded interpolation.
///
/// `phi(α)` evaluates the merit at the trial point (a non-finite value rejects the
/// trial); `phi0`, `dphi0` are the merit and its directional derivative at `α = 0`;
/// `reference` is `phi0` for the monotone rule or the nonmonotone average. A direction
/// with `dphi0 ≥ 0` is searched for plain decrease below `reference`.
pub fn armijo(
    mut phi: impl FnMut(f64) -> f64,
    phi0: f64,
    dphi0: f64,
    reference: f64,
    alpha_model: Option<f64>,
    opts: &LinesearchOptions,
) -> LinesearchResult {
    let slope = dphi0.min(0.0);
    let mut alpha = 1.0;
    let mut model = alpha_model.filter(|&a| a > opts.alpha_min && a < 1.0);
    let mut prev: Option<(f64, f64)> = None;
    let mut trials = 0;
    loop {
        let p = phi(alpha);
        trials += 1;
        if p.is_finite() && p <= reference + opts.c1 * alpha * slope {
            return LinesearchResult {
                alpha,
                phi: p,
                accepted: true,
                trials,
            };
        }
        if trials >= opts.max_trials || alpha <= opts.alpha_min {
            return LinesearchResult {
                alpha,
                phi: p,
                accepted: false,
                trials,
            };
        }
        let next = match model.take() {
            Some(a) => a,
            None => next_alpha(opts, phi0, slope, (alpha, p), prev).max(opts.alpha_min),
        };
        prev = Some((alpha, p));
        alpha = next;
    }
}

/// Reference value of the nonmonotone rule of Zhang & Hager (2004):
/// `C_{k+1} = (η Q_k C_k + φ_{k+1}) / Q_{k+1}`, `Q_{k+1} = η Q_k + 1`.
#[derive(Debug, Clone, Copy)]
pub struct Nonmonotone {
    eta: f64,
    c: f64,
    q: f64,
}

impl Nonmonotone {
    /// A rule with averaging weight `eta ∈ [0, 1]` (0 gives the monotone rule).
    pub fn new(eta: f64) -> Self {
        Self {
            eta: eta.clamp(0.0, 1.0),
            c: f64::NAN,
            q: 0.0,
        }
    }

    /// Restarts the average at `phi` (e.g. when the merit function changes).
    pub fn reset(&mut self, phi: f64) {
        self.c = phi;
        self.q = 1.0;
    }

    /// The reference value `C_k` (`phi0` if not started).
    pub fn reference(&self, phi0: f64) -> f64 {
        if self.c.is_finite() { self.c.max(phi0) } else { phi0 }
    }

    /// Records the merit value of the accepted iterate.
    pub fn update(&mut self, phi: f64) {
        if !self.c.is_finite() {
            self.reset(phi);
            return;
        }
        let q_next = self.eta * self.q + 1.0;
        self.c = (self.eta * self.q * self.c + phi) / q_next;
        self.q = q_next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_full_step_on_a_quadratic_with_newton_direction() {
        // φ(α) = (1 - α)², φ'(0) = -2: the Newton step α = 1 is exact.
        let r = armijo(
            |a| (1.0 - a) * (1.0 - a),
            1.0,
            -2.0,
            1.0,
            None,
            &LinesearchOptions::default(),
        );
        assert!(r.accepted);
        assert_eq!((r.alpha, r.trials), (1.0, 1));
    }

    #[test]
    fn interpolation_finds_the_minimiser_of_a_quadratic_in_one_backtrack() {
        // φ(α) = (α - 0.3)² with φ'(0) = -0.6: the quadratic model is exact, so the
        // first interpolated trial is the minimiser 0.3.
        let f = |a: f64| (a - 0.3) * (a - 0.3);
        let r = armijo(f, f(0.0), -0.6, f(0.0), None, &LinesearchOptions::default());
        assert!(r.accepted);
        assert_eq!(r.trials, 2);
        assert!((r.alpha - 0.3).abs() < 1e-15);
        // Cubic: φ(α) = α³ - α, φ'(0) = -1; α = 1 gives φ = 0 > c1·(-1), rejected;
        // the interpolation then proposes values in [0.1, 0.5] that are accepted.
        let g = |a: f64| a * a * a - a;
        let r = armijo(g, 0.0, -1.0, 0.0, None, &LinesearchOptions::default());
        assert!(r.accepted && r.alpha <= 0.5 && r.alpha >= 0.1, "{r:?}");
        assert!(g(r.alpha) <= -(1e-4 * r.alpha));
    }

    #[test]
    fn the_model_step_is_tried_after_the_full_step() {
        // φ(α) = (α - 0.37)²: the full step fails, the model minimiser is accepted at once.
        let f = |a: f64| (a - 0.37) * (a - 0.37);
        let r = armijo(f, f(0.0), -0.74, f(0.0), Some(0.37), &LinesearchOptions::default());
        assert!(r.accepted);
        assert_eq!((r.alpha, r.trials), (0.37, 2));
    }

    #[test]
    fn non_finite_trials_are_rejected_and_ascent_fails() {
        let r = armijo(
            |a| if a > 0.3 { f64::NAN } else { -a },
            0.0,
            -1.0,
            0.0,
            None,
            &LinesearchOptions::default(),
        );
        assert!(r.accepted && r.alpha <= 0.3);
        let opts = LinesearchOptions {
            max_trials: 5,
            ..Default::default()
        };
        let r = armijo(|a| a, 0.0, 1.0, 0.0, None, &opts);
        assert!(!r.accepted);
        assert_eq!(r.trials, 5);
    }

    #[test]
    fn nonmonotone_reference_is_the_weighted_average() {
        let mut nm = Nonmonotone::new(0.5);
        nm.reset(10.0);
        nm.update(4.0);
        // C = (0.5·1·10 + 4) / 1.5 = 6
        assert!((nm.reference(0.0) - 6.0).abs() < 1e-14);
        nm.update(1.0);
        // Q = 1.75, C = (0.5·1.5·6 + 1) / 1.75
        assert!((nm.reference(0.0) - (0.75 * 6.0 + 1.0) / 1.75).abs() < 1e-14);
        let mono = Nonmonotone::new(0.0);
        assert_eq!(mono.reference(3.0), 3.0);
    }

    #[test]
    fn options_are_validated() {
        assert!(LinesearchOptions::default().validate().is_ok());
        let bad = LinesearchOptions {
            c1: 0.7,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
    }
}
