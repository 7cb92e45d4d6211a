//! The run's status line on stderr: what the planner node does until the first plan step (or,
//! in a split run, which input from the other host it waits for), then how far the run has
//! got.

use super::Watch;

impl Watch {
    /// The status line: what the planner node does until the first plan step (in a split run,
    /// once it has planned or where it plans on the other host, the inputs from the other
    /// host that have not come yet, and over which link), then how far the run has got
    /// (`now`: drawn now, whatever the period).
    pub(super) fn show(&mut self, now: bool) {
        if !self.status.due(now) {
            return;
        }
        let l = &self.limits;
        let elapsed = l.started.elapsed().as_secs_f64();
        let waiting: Vec<&str> = l
            .imports
            .iter()
            .filter(|t| !self.arrived.contains(*t))
            .copied()
            .collect();
        let text = match (&self.first_plan, &self.planning) {
            (None, Some(doing)) if !self.planned || waiting.is_empty() => {
                format!("run: the planner node is {doing}, {elapsed:.1} s")
            }
            // The processes' start: said once it takes a while.
            (None, None) if !now && elapsed < crate::run::status::LINE_EVERY.as_secs_f64() => {
                return;
            }
            (None, _) if !waiting.is_empty() => format!(
                "run: waiting for {} from the other host ({}), {elapsed:.1} s",
                waiting.join(" and "),
                l.link
            ),
            (None, _) => format!("run: waiting for the first plan step, {elapsed:.1} s"),
            (Some(_), _) => format!(
                "run: {:.1} of {:.1} deg | {} switches | min alpha* {} (alpha {}) | {} holds | {} restarts | {elapsed:.1} s",
                self.rotation.to_degrees(),
                l.goal.to_degrees(),
                self.attaches.len(),
                if self.min_quality.is_finite() {
                    format!("{:.4}", self.min_quality)
                } else {
                    "-".into()
                },
                l.alpha,
                self.holds,
                self.restarts
            ),
        };
        self.status.update(now, || text);
    }
}
