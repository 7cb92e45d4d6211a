//! # icrflow-runtime: the pipeline's plumbing
//!
//! What every process of the pipeline shares, and nothing of grasps:
//!
//! | module | what |
//! |---|---|
//! | [`bus`] | the run's isolated iceoryx2 bus: typed topics as publisher + notifier and subscriber + listener pairs |
//! | [`event`] | the event loop every node runs (`ppoll` on the listeners, a tick, a resync); only a termination signal (SIGTERM, SIGINT) ends it |
//! | [`launch`] | what a node is started with: one typed description, handed over as its arguments |
//! | [`node`] | a node process: what it is started with, what it loads, its bus, its supervisor, real-time priority |
//! | [`health`] | health reports, sequence numbers, heap-allocation counts |
//! | [`checkpoint`] | a node's state kept on disk for its restart |
//! | [`supervise`] | starting, watching and restarting the node processes |

#![warn(missing_docs)]

pub mod bus;
pub mod checkpoint;
pub mod event;
pub mod health;
pub mod launch;
pub mod node;
pub mod supervise;
