//! Node processes refuse what is not theirs, and say so: the real `icrflow-estimator` binary on
//! an isolated bus, facing a topic of another message type, then messages of another schema
//! version.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use icrflow_interfaces::{
    HandCommand, Header, JointState, Kind, SCHEMA_VERSION, read_text, topics,
};
use icrflow_runtime::bus::{Bus, BusConfig};
use icrflow_runtime::launch::Launch;

/// The paper scenario's config.
fn config() -> PathBuf {
    let dir =
        std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into());
    PathBuf::from(dir).join("../config/paper_sphere.toml")
}

/// The estimator process on bus `c`.
fn estimator(c: &BusConfig) -> Child {
    Command::new(env!("CARGO_BIN_EXE_icrflow-estimator"))
        .args(Launch::new(config(), c.clone()).to_args())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting icrflow-estimator")
}

/// Waits up to 30 s for `child` to exit (killing it after that); its exit code and stderr.
fn finish(mut child: Child) -> (Option<i32>, String) {
    let end = Instant::now() + Duration::from_secs(30);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > end {
            let _ = child.kill();
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_node_facing_a_topic_of_another_message_type_exits_naming_both() {
    let c = BusConfig::isolated("wrongtype").unwrap();
    let (code, err) = {
        // Another program made the joint-state topic with hand commands on it.
        let bus = Bus::new("intruder", &c).unwrap();
        let _wrong = bus
            .publisher_named::<HandCommand>(topics::JOINT_STATE.name())
            .unwrap();
        finish(estimator(&c))
    };
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("icrflow-estimator: error"), "{err}");
    assert!(err.contains("icrflow/test/joint_state"), "{err}");
    assert!(
        err.contains(&format!("icrflow.JointState.v{SCHEMA_VERSION}")),
        "{err}"
    );
    assert!(err.contains("refusing to connect"), "{err}");
    c.remove_files();
}

#[test]
fn a_node_refuses_messages_of_another_schema_version_and_reports_why() {
    let c = BusConfig::isolated("schema").unwrap();
    let child = estimator(&c);
    let (refusal, estimates) = {
        let bus = Bus::new("old-plant", &c).unwrap();
        let joints = bus.publisher(topics::JOINT_STATE).unwrap();
        let health = bus.subscriber(topics::NODE_HEALTH).unwrap();
        let grasps = bus.subscriber(topics::GRASP_STATE).unwrap();
        let (mut refusal, mut estimates) = (None, 0);
        let end = Instant::now() + Duration::from_secs(20);
        let mut sequence = 0;
        while refusal.is_none() && Instant::now() < end {
            sequence += 1;
            let mut m = JointState {
                header: Header::new(Kind::JointState, sequence, 0, 0),
                ..Default::default()
            };
            m.header.schema = SCHEMA_VERSION - 1;
            joints.publish(m).unwrap();
            std::thread::sleep(Duration::from_millis(2));
            health
                .drain(|h| {
                    if read_text(&h.node) == "estimator" && h.refused > 0 {
                        refusal = Some((h.refused, h.processed, read_text(&h.message)));
                    }
                })
                .unwrap();
            estimates += grasps.drain(|_| {}).unwrap();
        }
        (refusal, estimates)
    };
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    )
    .unwrap();
    let (code, err) = finish(child);
    let (refused, processed, why) = refusal.expect("no health report with a refusal in 20 s");
    assert!(
        refused > 0 && processed == 0,
        "{refused} refused, {processed} processed"
    );
    assert!(
        why.contains(&format!(
            "schema version {}, expected {SCHEMA_VERSION}",
            SCHEMA_VERSION - 1
        )),
        "{why}"
    );
    assert_eq!(estimates, 0, "the estimator estimated from refused input");
    assert_eq!(code, Some(0), "SIGTERM stops the node cleanly: {err}");
    assert!(c.leftovers().is_empty(), "{:?}", c.leftovers());
    c.remove_files();
}
