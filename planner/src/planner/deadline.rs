//! When a plan's time runs out ([`Settings::max_plan`](super::Settings::max_plan),
//! `plan.max_plan_s`): the planning loop asks before every step, a spatial switch search
//! between its batches. The only clock that affects a plan (the planner's phase timings only
//! measure); a plan that ends within its time is the same whatever the machine's speed.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// The end of a plan's time, or none.
#[derive(Debug)]
pub(crate) struct Deadline {
    /// When the time runs out (`None`: never).
    at: Option<Instant>,
    /// The time given (for the stop reason).
    pub(crate) budget: Option<Duration>,
    /// A test's deadline: how many more times it is asked before it has passed.
    asks: Option<AtomicUsize>,
}

impl Deadline {
    /// `budget` from now (`None`: no bound).
    pub(crate) fn after(budget: Option<Duration>) -> Self {
        Self {
            at: budget.and_then(|b| Instant::now().checked_add(b)),
            budget,
            asks: None,
        }
    }

    /// A deadline that has passed from the `n + 1`-th time it is asked on, whatever the
    /// clock: where a test stops a plan, exactly.
    #[cfg(test)]
    pub(crate) fn after_asking(n: usize) -> Self {
        Self {
            at: None,
            budget: Some(Duration::ZERO),
            asks: Some(AtomicUsize::new(n)),
        }
    }

    /// Whether the time has run out.
    pub(crate) fn passed(&self) -> bool {
        match &self.asks {
            Some(left) => left
                .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| n.checked_sub(1))
                .is_err(),
            None => self.at.is_some_and(|at| Instant::now() >= at),
        }
    }
}
