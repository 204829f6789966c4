//! Filter step acceptance (Fletcher & Leyffer 2002, with the margins of Wächter &
//! Biegler's IPOPT).
//!
//! The filter stores pairs `(φ_j, θ_j)` of a merit (or cost) value and an infeasibility
//! measure. A trial `(φ, θ)` is acceptable when no stored pair dominates it, with
//! margins: for every `j`, `θ ≤ (1 - γ_θ) θ_j` **or** `φ ≤ φ_j - γ_φ θ_j`.
//! Adding a pair removes the stored pairs it dominates (`φ ≤ φ_j` and `θ ≤ θ_j`), so the
//! filter stays a Pareto front.
//!
//! As in IPOPT's switching rule, a step that decreases the merit function enough for the
//! Armijo condition (an "f-type" step) is accepted without consulting the filter and
//! leaves it unchanged: close to a solution the infeasibility no longer changes while the
//! merit still decreases by amounts far below the filter's margins.
//!
//! Whatever the filter holds, a trial must also be acceptable to the current iterate
//! (with the same margins) and its infeasibility must stay below `θ_max` (IPOPT's upper
//! bound, set once per solve): an empty filter (after a penalty update) then cannot
//! accept a trial whose rollout exploded.

use super::linesearch::{LinesearchOptions, LinesearchResult};

/// The largest capacity of a [`Filter`]: a Pareto front of that many pairs is far more
/// than any solve keeps (when full, the most infeasible pair is dropped).
pub const MAX_FILTER_ENTRIES: usize = 1_000;

/// A filter of `(φ, θ)` pairs with a fixed capacity (allocated once).
#[derive(Debug, Clone)]
pub struct Filter {
    entries: Vec<(f64, f64)>,
    capacity: usize,
    gamma_phi: f64,
    gamma_theta: f64,
    theta_max: f64,
    theta_min: f64,
    /// The next trial is taken whole if bounded (set by [`Filter::new`] and
    /// [`Filter::clear`]).
    free_step: bool,
}

impl Filter {
    /// An empty filter holding at most `capacity` pairs ([`MAX_FILTER_ENTRIES`] at
    /// most, 1 at least), with margins `gamma_phi`, `gamma_theta` (typically `1e-5`).
    pub fn new(capacity: usize, gamma_phi: f64, gamma_theta: f64) -> Self {
        let capacity = capacity.clamp(1, MAX_FILTER_ENTRIES);
        Self {
            entries: Vec::with_capacity(capacity),
            capacity,
            gamma_phi,
            gamma_theta,
            theta_max: f64::INFINITY,
            theta_min: 0.0,
            free_step: true,
        }
    }

    /// Sets the largest infeasibility a trial may have (IPOPT uses
    /// `1e4 · max(1, θ(x_0))`); [`Filter::clear`] keeps it.
    pub fn set_theta_max(&mut self, theta_max: f64) {
        self.theta_max = theta_max;
    }

    /// Removes every pair. The first trial after a clear (and after [`Filter::new`]) is
    /// taken whole when its infeasibility is below `θ_max`: the merit function has just
    /// changed (new multipliers or penalty), and the semi-smooth Newton step of the new
    /// subproblem must be able to cross the kinks where constraints become active.
    pub fn clear(&mut self) {
        self.entries.clear();
        self.free_step = true;
    }

    /// The stored pairs.
    pub fn entries(&self) -> &[(f64, f64)] {
        &self.entries
    }

    /// Whether `(phi, theta)` is acceptable to the filter.
    pub fn is_acceptable(&self, phi: f64, theta: f64) -> bool {
        if !(phi.is_finite() && theta.is_finite()) {
            return false;
        }
        self.entries
            .iter()
            .all(|&(pj, tj)| self.acceptable_to(phi, theta, pj, tj))
    }

    fn acceptable_to(&self, phi: f64, theta: f64, pj: f64, tj: f64) -> bool {
        theta <= (1.0 - self.gamma_theta) * tj || phi <= pj - self.gamma_phi * tj
    }

    /// Sets the infeasibility below which a trial must satisfy the Armijo condition
    /// (IPOPT's `θ_min`): once the current iterate is that feasible, only the merit
    /// function ranks steps, and the filter can no longer trade merit increases for
    /// tiny reductions of an infeasibility that need not go to zero.
    pub fn set_theta_min(&mut self, theta_min: f64) {
        self.theta_min = theta_min;
    }

    /// Adds `(phi, theta)`, removing the pairs it dominates. When the filter is full
    /// the pair with the largest infeasibility is dropped first.
    pub fn add(&mut self, phi: f64, theta: f64) {
        if !(phi.is_finite() && theta.is_finite()) {
            return;
        }
        self.entries.retain(|&(pj, tj)| !(phi <= pj && theta <= tj));
        if self.entries.len() == self.capacity {
            let worst = self
                .entries
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.1.total_cmp(&b.1.1))
                .map(|(i, _)| i)
                .unwrap_or(0);
            self.entries.swap_remove(worst);
        }
        self.entries.push((phi, theta));
    }

    /// Backtracking search for an acceptable step: the full step first, then
    /// `alpha_model` (a model minimiser, when given and in `(0, 1)`), then halving.
    /// `trial(α)` returns `(φ(α), θ(α))`; `(phi0, theta0)` is the current iterate and
    /// `dphi0` the merit slope at `α = 0`. A trial with `θ ≤ θ_max` is accepted when it
    /// satisfies the Armijo condition on `φ` (the filter is left unchanged), is the full
    /// step of a new subproblem (first trial after [`Filter::new`] or [`Filter::clear`]),
    /// or is acceptable both to the filter and to the current iterate while
    /// `theta0 > θ_min` (in the last two cases it is added).
    pub fn search(
        &mut self,
        mut trial: impl FnMut(f64) -> (f64, f64),
        (phi0, theta0): (f64, f64),
        dphi0: f64,
        alpha_model: Option<f64>,
        opts: &LinesearchOptions,
    ) -> LinesearchResult {
        let mut alpha = 1.0;
        let mut model = alpha_model.filter(|&a| a > opts.alpha_min && a < 1.0);
        let slope = dphi0.min(0.0);
        let mut trials = 0;
        loop {
            let (phi, theta) = trial(alpha);
            trials += 1;
            let bounded = phi.is_finite() && theta.is_finite() && theta <= self.theta_max;
            let armijo = bounded && phi <= phi0 + opts.c1 * alpha * slope && slope < 0.0;
            let free = std::mem::take(&mut self.free_step);
            let filter = bounded
                && !armijo
                && (free
                    || (theta0 > self.theta_min
                        && self.is_acceptable(phi, theta)
                        && self.acceptable_to(phi, theta, phi0, theta0)));
            if armijo || filter {
                if filter {
                    self.add(phi, theta);
                }
                return LinesearchResult {
                    alpha,
                    phi,
                    accepted: true,
                    trials,
                };
            }
            if trials >= opts.max_trials || alpha <= opts.alpha_min {
                return LinesearchResult {
                    alpha,
                    phi,
                    accepted: false,
                    trials,
                };
            }
            alpha = match model.take() {
                Some(a) => a,
                None => (alpha * opts.contraction_max).max(opts.alpha_min),
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dominance_and_margins() {
        let mut f = Filter::new(8, 1e-5, 1e-5);
        f.add(10.0, 1.0);
        f.add(5.0, 2.0);
        // Better in θ than the first pair: acceptable.
        assert!(f.is_acceptable(20.0, 0.5));
        // Better in φ than both pairs (with margin): acceptable.
        assert!(f.is_acceptable(4.0, 3.0));
        // Worse in both than (5, 2): rejected.
        assert!(!f.is_acceptable(6.0, 2.5));
        // Equal to a stored pair: rejected by the margins.
        assert!(!f.is_acceptable(5.0, 2.0));
        // Between the pairs: (7, 1.5) is worse than (5, 2) in φ but better in θ, and
        // better than (10, 1) in φ: acceptable.
        assert!(f.is_acceptable(7.0, 1.5));
        // Adding a pair that dominates both leaves only it.
        f.add(1.0, 0.1);
        assert_eq!(f.entries(), &[(1.0, 0.1)]);
        assert!(!f.is_acceptable(f64::NAN, 0.0));
    }

    #[test]
    fn sufficient_merit_decrease_is_accepted_without_the_filter() {
        let mut f = Filter::new(8, 1e-5, 1e-5);
        f.add(1.0, 1.0);
        // Dominated by (1, 1) with margins, but an Armijo decrease of the merit from
        // φ(0) = 1.0 + 1e-12 along slope -1e-9: accepted, the filter is unchanged.
        let r = f.search(
            |_| (1.0, 1.0),
            (1.0 + 1e-12, 1.0),
            -1e-9,
            None,
            &LinesearchOptions::default(),
        );
        assert!(r.accepted && r.alpha == 1.0);
        assert_eq!(f.entries(), &[(1.0, 1.0)]);
    }

    #[test]
    fn capacity_drops_the_most_infeasible_pair() {
        let mut f = Filter::new(2, 0.0, 0.0);
        f.add(1.0, 3.0);
        f.add(2.0, 2.0);
        f.add(3.0, 1.0);
        assert_eq!(f.entries().len(), 2);
        assert!(f.entries().iter().all(|&(_, t)| t < 3.0));
    }

    #[test]
    fn search_backtracks_until_acceptable() {
        let mut f = Filter::new(8, 1e-5, 1e-5);
        // The free first step of a new filter.
        let r = f.search(|_| (5.0, 5.0), (10.0, 10.0), 0.0, None, &LinesearchOptions::default());
        assert!(r.accepted && r.alpha == 1.0);
        assert_eq!(f.entries(), &[(5.0, 5.0)]);
        // Trials are better than (5, 5) only for α ≤ 0.25.
        let r = f.search(
            |a| if a > 0.25 { (6.0, 6.0) } else { (0.5, 0.5) },
            (10.0, 10.0),
            0.0,
            None,
            &LinesearchOptions::default(),
        );
        assert!(r.accepted);
        assert_eq!(r.alpha, 0.25);
        assert_eq!(f.entries(), &[(0.5, 0.5)]);
        // A model step is tried right after the full step.
        let mut g = past_first_step(Filter::new(8, 1e-5, 1e-5));
        g.add(1.0, 1.0);
        let r = g.search(
            |a| if a == 0.3 { (0.1, 0.1) } else { (9.0, 9.0) },
            (2.0, 2.0),
            0.0,
            Some(0.3),
            &LinesearchOptions::default(),
        );
        assert!(r.accepted && r.alpha == 0.3 && r.trials == 2);
        // A trial equal to a stored pair is rejected until the trial limit.
        let opts = LinesearchOptions {
            max_trials: 3,
            ..Default::default()
        };
        let r = f.search(|_| (0.5, 0.5), (10.0, 10.0), 0.0, None, &opts);
        assert!(!r.accepted);
        assert_eq!(r.trials, 3);
    }

    /// A filter whose free first step has been used.
    fn past_first_step(mut f: Filter) -> Filter {
        f.free_step = false;
        f
    }

    #[test]
    fn the_first_step_is_free_if_bounded_and_later_steps_must_beat_the_current_point() {
        let opts = LinesearchOptions::default();
        let mut f = Filter::new(8, 1e-5, 1e-5);
        f.set_theta_max(10.0);
        // The full step of a new subproblem is taken although worse than the current
        // point (1, 1) in both measures: θ = 5 ≤ θ_max.
        let r = f.search(|_| (1e3, 5.0), (1.0, 1.0), 0.0, None, &opts);
        assert!(r.accepted && r.alpha == 1.0, "{r:?}");
        assert_eq!(f.entries(), &[(1e3, 5.0)]);
        // Next search: (1e200, 2) is acceptable to the filter but worse than the current
        // point, so the search backtracks to α ≤ 0.1.
        let r = f.search(
            |a| if a > 0.1 { (1e200, 2.0) } else { (0.9, 0.9) },
            (1.0, 1.0),
            0.0,
            None,
            &opts,
        );
        assert!(r.accepted && r.alpha <= 0.1 && r.alpha > 0.05, "{r:?}");
        // After a clear the full step is free again, but never above θ_max, even with
        // an Armijo decrease of φ.
        f.clear();
        let r = f.search(
            |a| if a > 0.3 { (0.0, 20.0) } else { (0.5, 5.0) },
            (1.0, 1.0),
            -1.0,
            None,
            &opts,
        );
        assert!(r.accepted && r.alpha <= 0.3 && r.phi == 0.5, "{r:?}");
        f.clear();
        let r = f.search(|_| (0.0, 20.0), (1.0, 1.0), -1.0, None, &opts);
        assert!(!r.accepted);
    }

    #[test]
    fn below_theta_min_only_the_armijo_condition_accepts() {
        let opts = LinesearchOptions {
            max_trials: 3,
            ..Default::default()
        };
        // The merit rises, the infeasibility drops by 1 %: a filter (h-type) step.
        let step = |_: f64| (1.1, 0.99e-5);
        let mut f = past_first_step(Filter::new(8, 1e-5, 1e-5));
        assert!(f.search(step, (1.0, 1e-5), -1e-3, None, &opts).accepted);
        let mut g = past_first_step(Filter::new(8, 1e-5, 1e-5));
        g.set_theta_min(1e-4);
        let r = g.search(step, (1.0, 1e-5), -1e-3, None, &opts);
        assert!(!r.accepted && r.trials == 3);
        // An Armijo decrease is still accepted.
        assert!(
            g.search(|a| (1.0 - 1e-3 * a, 1e-5), (1.0, 1e-5), -1e-3, None, &opts)
                .accepted
        );
    }
}
