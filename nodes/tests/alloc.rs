//! Heap allocations of the bus in its steady state, counted by the allocator the node
//! binaries install (`runtime::COUNTING_ALLOCATOR`): receiving allocates nothing; sending
//! allocates once, inside iceoryx2 0.10 (`Publisher::loan_uninit` creates a reference-counted
//! `ChunkMutSharedState` per sample), which no use of its API avoids.

use icrflow_interfaces::{Header, JointState, Kind, topics};
use icrflow_nodes::bus::Bus;
use icrflow_nodes::runtime::allocations;

mod common;
use common::{isolated, remove};

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

#[test]
fn receiving_allocates_nothing_and_sending_once() {
    let c = isolated("alloc");
    {
        let a = Bus::new("sender", &c).unwrap();
        let b = Bus::new("receiver", &c).unwrap();
        let sub = b.subscriber::<JointState>(topics::JOINT_STATE).unwrap();
        let publisher = a.publisher::<JointState>(topics::JOINT_STATE).unwrap();
        let m = JointState {
            header: Header::new(Kind::JointState, 1, 0, 0),
            ..Default::default()
        };
        // Warm up: connections, buffers.
        for _ in 0..100 {
            publisher.send(m).unwrap();
            sub.drain(|_| {}).unwrap();
        }
        let n = 1000;
        let mut counts = [0u64; 3];
        for _ in 0..n {
            let t0 = allocations();
            publisher.send(m).unwrap();
            let t1 = allocations();
            sub.drain(|_| {}).unwrap();
            let t2 = allocations();
            counts[0] += t1 - t0;
            counts[1] += t2 - t1;
        }
        let t0 = allocations();
        for _ in 0..n {
            sub.latest().unwrap();
        }
        counts[2] = allocations() - t0;
        println!(
            "per operation: send {:.2}, drain {:.2}, empty latest {:.2}",
            counts[0] as f64 / n as f64,
            counts[1] as f64 / n as f64,
            counts[2] as f64 / n as f64
        );
        assert!(counts[0] <= n, "send allocates more than once: {counts:?}");
        assert_eq!(counts[1], 0, "draining a message allocates");
        assert_eq!(counts[2], 0, "polling an empty subscriber allocates");
    }
    remove(&c);
}
