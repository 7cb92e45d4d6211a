//! # icrflow-nodes: the pipeline's processes
//!
//! The plumbing every node shares ([`bus`]: the run's isolated iceoryx2 bus, topics as
//! publisher + notifier and subscriber + listener pairs) and the hand command node's
//! [`safety`] gate. The node binaries (state estimator,
//! wrench-space node, ICR planner, hand command node, sim plant; issue #4) build on it.

#![warn(missing_docs)]

pub mod bus;
pub mod command;
pub mod estimator;
pub mod planner;
pub mod plant;
pub mod rolling;
pub mod runtime;
pub mod safety;
pub mod supervise;
pub mod wrench;
