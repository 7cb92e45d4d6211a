//! The bus over real iceoryx2 services, in an isolated prefix and root: delivery with a
//! WaitSet wake-up, refusal of a mismatched message type, and no resources left behind.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::time::Duration;

use iceoryx2::prelude::*;
use icrflow_interfaces::{HandCommand, Header, JointState, Kind, SCHEMA_VERSION, topics};
use std::path::PathBuf;

use icrflow_runtime::bus::{Bus, BusConfig, BusError};

#[test]
fn a_message_wakes_the_subscriber_and_arrives_intact() {
    let c = BusConfig::isolated("deliver").unwrap();
    {
        let a = Bus::new("sender", &c).unwrap();
        let b = Bus::new("receiver", &c).unwrap();
        let sub = b.subscriber(topics::JOINT_STATE).unwrap();
        let publisher = a.publisher(topics::JOINT_STATE).unwrap();
        let mut m = JointState {
            header: Header::new(Kind::JointState, 1, 0, 0),
            finger_count: 2,
            ..Default::default()
        };
        m.positions[1][2] = 0.25;
        assert_eq!(publisher.send(m).unwrap(), 1);
        let ws = WaitSetBuilder::new().create::<ipc::Service>().unwrap();
        let guard = ws.attach_notification(sub.listener()).unwrap();
        let mut got = None;
        ws.wait_and_process_once_with_timeout(
            |id| {
                if id.has_event_from(&guard) {
                    got = sub.latest().unwrap();
                }
                CallbackProgression::Stop
            },
            Duration::from_secs(5),
        )
        .unwrap();
        drop(guard);
        let got = got.expect("the WaitSet woke with the message");
        assert_eq!(got, m);
        assert!(got.header.check(Kind::JointState).is_ok());
    }
    assert_eq!(c.leftovers(), Vec::<String>::new());
    c.remove_files();
}

#[test]
fn a_mismatched_message_type_is_refused_by_name() {
    let c = BusConfig::isolated("mismatch").unwrap();
    {
        let a = Bus::new("sender", &c).unwrap();
        let _p = a.publisher(topics::JOINT_STATE).unwrap();
        let b = Bus::new("wrong", &c).unwrap();
        let e = match b.subscriber_named::<HandCommand>(topics::JOINT_STATE.name()) {
            Err(e) => e,
            Ok(_) => panic!("a HandCommand subscriber connected to the joint-state topic"),
        };
        assert!(matches!(e, BusError::Mismatch { .. }), "{e}");
        let text = e.to_string();
        assert!(text.contains("icrflow/test/joint_state"), "{text}");
        assert!(
            text.contains(&format!("icrflow.HandCommand.v{SCHEMA_VERSION}")),
            "{text}"
        );
    }
    c.remove_files();
}

#[test]
fn bad_settings_are_named() {
    assert!(BusConfig::new("rig one", "p", PathBuf::from("/tmp/x")).is_err());
    assert!(BusConfig::new("rig", "p/x", PathBuf::from("/tmp/x")).is_err());
    let e = BusConfig::new("rig", "p", PathBuf::from("relative")).unwrap_err();
    assert!(e.to_string().contains("absolute"), "{e}");
}
