//! The supervisor with real child processes: restarts with backoff until the policy gives up,
//! SIGKILLed nodes restarted, SIGTERM then SIGKILL on shutdown.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::path::PathBuf;
use std::time::{Duration, Instant};

use icrflow_runtime::bus::BusConfig;
use icrflow_runtime::supervise::{Event, NodeSpec, RestartPolicy, Supervisor};

fn bus(tag: &str) -> BusConfig {
    BusConfig::new(
        "test",
        &format!("icrs_{tag}_{}_", std::process::id()),
        PathBuf::from(format!("/tmp/icrflow-sup-{tag}-{}", std::process::id())),
    )
    .unwrap()
}

fn sh(name: &str, script: &str, policy: RestartPolicy) -> NodeSpec {
    NodeSpec {
        name: name.into(),
        program: PathBuf::from("/bin/sh"),
        args: vec!["-c".into(), script.into()],
        policy,
        essential: true,
        launch: None,
    }
}

fn fast(max_restarts: u32) -> RestartPolicy {
    RestartPolicy {
        max_restarts,
        window: Duration::from_secs(30),
        backoff: Duration::from_millis(10),
        max_backoff: Duration::from_millis(40),
    }
}

/// Polls until `until` says stop or 10 s pass; returns every event.
fn run(s: &mut Supervisor, mut until: impl FnMut(&[Event]) -> bool) -> Vec<Event> {
    let mut all = Vec::new();
    let end = Instant::now() + Duration::from_secs(10);
    while Instant::now() < end && !until(&all) {
        all.extend(s.poll(Instant::now()).unwrap());
        std::thread::sleep(Duration::from_millis(5));
    }
    all
}

#[test]
fn a_failing_node_is_restarted_until_the_policy_gives_up() {
    let mut s = Supervisor::new(bus("giveup"), vec![sh("flaky", "exit 3", fast(2))], true);
    s.start().unwrap();
    let events = run(&mut s, |e| {
        e.iter().any(|x| matches!(x, Event::GaveUp { .. }))
    });
    let exits = events
        .iter()
        .filter(|e| matches!(e, Event::Exited { status, .. } if status == "exit code 3"))
        .count();
    assert_eq!(exits, 3, "{events:?}");
    assert_eq!(s.restarts(), 2);
    assert_eq!(s.failed(), Some("flaky"));
    let Some(Event::GaveUp { reason, .. }) = events.last() else {
        panic!("{events:?}")
    };
    assert!(reason.contains("2 restarts"), "{reason}");
}

#[test]
fn a_killed_node_is_restarted_and_shutdown_escalates_to_sigkill() {
    let mut s = Supervisor::new(
        bus("kill"),
        vec![
            sh("steady", "exec sleep 30", fast(3)),
            sh("stubborn", "trap '' TERM; exec sleep 30", fast(3)),
        ],
        true,
    );
    s.start().unwrap();
    let pid = s.pid("steady").unwrap();
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(pid as i32),
        nix::sys::signal::Signal::SIGKILL,
    )
    .unwrap();
    let events = run(&mut s, |e| {
        e.iter()
            .any(|x| matches!(x, Event::Started { attempt: 1, .. }))
    });
    assert!(
        events.iter().any(
            |e| matches!(e, Event::Exited { name, status, .. } if name == "steady" && status == "killed by SIGKILL")
        ),
        "{events:?}"
    );
    let new_pid = s.pid("steady").unwrap();
    assert_ne!(new_pid, pid);
    // SIGTERM stops `steady`; `stubborn` ignores it and is killed after the grace period.
    let stubborn = s.pid("stubborn").unwrap();
    let started = Instant::now();
    let killed = s.shutdown(Duration::from_millis(300));
    assert_eq!(killed, vec!["stubborn".to_string()]);
    assert!(started.elapsed() >= Duration::from_millis(300));
    assert!(s.pid("steady").is_none() && s.pid("stubborn").is_none());
    // Both processes are gone (reaped, so not even zombies).
    for p in [new_pid, stubborn] {
        assert!(!std::path::Path::new(&format!("/proc/{p}")).exists());
    }
}

/// A node started first (the run's visualizer, which must listen before the loop begins) runs
/// alone; `start` then starts the others and leaves it be, even after it exited and is in
/// its restart backoff.
#[test]
fn a_node_started_first_runs_alone_until_the_others_start() {
    let slow = RestartPolicy {
        backoff: Duration::from_secs(20),
        max_backoff: Duration::from_secs(20),
        ..fast(3)
    };
    let mut s = Supervisor::new(
        bus("first"),
        vec![
            sh("loop", "exec sleep 30", fast(3)),
            sh("viewer", "exit 0", slow),
        ],
        true,
    );
    let events = s.start_first("viewer").unwrap();
    assert!(
        matches!(&events[..], [Event::Started { name, attempt: 0, .. }] if name == "viewer"),
        "{events:?}"
    );
    assert_eq!(s.pid("loop"), None);
    let events = run(&mut s, |e| {
        e.iter().any(|x| matches!(x, Event::Exited { .. }))
    });
    assert!(
        matches!(&events[..], [Event::Exited { name, .. }] if name == "viewer"),
        "{events:?}"
    );
    // `start` starts the rest only: the exited viewer waits out its backoff.
    let events = s.start().unwrap();
    assert!(
        matches!(&events[..], [Event::Started { name, .. }] if name == "loop"),
        "{events:?}"
    );
    assert!(s.pid("loop").is_some());
    assert_eq!(s.pid("viewer"), None);
    assert!(s.start().unwrap().is_empty(), "started twice");
    s.shutdown(Duration::from_millis(300));
}
