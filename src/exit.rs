//! The exit statuses every verb shares (README, "Exit statuses"; `icrflow --help`):
//!
//! | status | meaning |
//! |---|---|
//! | 0 | done: the config is valid, the grasp force closure with alpha* >= alpha, the plan or run at its goal |
//! | 1 | error: bad input, a missing file, a failure; the message names it |
//! | 2 | the verb did its work and the answer is no: the grasp is not force closure, or its quality is below the margin alpha, or the plan or run stopped before its goal |

use icrflow_plan::planner::PlanError;

/// Done.
pub const DONE: u8 = 0;
/// The work was done and the answer is no (see the module's docs).
pub const INCOMPLETE: u8 = 2;

/// Whether planning's refusal to start is an answer about the grasp (not force closure, below
/// the margin: exit status [`INCOMPLETE`]) rather than an error in the input.
pub fn is_grasp_answer(e: &PlanError) -> bool {
    matches!(
        e,
        PlanError::NotForceClosure { .. } | PlanError::BelowMargin { .. }
    )
}

/// The `after_help` of `icrflow --help`: the exit statuses.
pub const HELP: &str = "Exit status: 0 done; 1 error (the message names it); 2 the work was done and \
the answer is no: the grasp is not force closure or below the margin alpha, or the plan or run \
stopped before its goal.";
