//! The topics the bridge carries and their message types, written once ([`visit`]): the
//! monitoring forwards (`crate::run`), the exports and the imports between hosts
//! (`crate::link`) each open their ports through it, so a topic's type is named in one place
//! and a topic added to the table is carried every way.

use std::fmt::Debug;

use anyhow::{Result, anyhow};
use iceoryx2::prelude::ZeroCopySend;
use icrflow_interfaces::topics::{self, SliceTopic, Topic, TopicId};
use icrflow_interfaces::{
    Facet, GraspState, HandCommand, JointState, Message, NodeHealth, ObjectPose, PlanStepHeader,
    WrenchSpaceHeader,
};
use zerocopy::{FromBytes, Immutable, IntoBytes};

use crate::json;

/// A message the bridge carries whole: as bytes between hosts, and as JSON to monitoring
/// clients.
pub trait Whole:
    Message + IntoBytes + FromBytes + Immutable + ZeroCopySend + Debug + Copy + 'static
{
    /// Whether the bridge publishes it for monitoring.
    const MONITORED: bool = true;

    /// Writes its monitoring JSON into `out` (cleared first); an error if it is not monitored.
    fn write_json(&self, rig: &str, out: &mut Vec<u8>) -> Result<()>;
}

/// A header the bridge carries with a slice of [`Sliced::Item`]s.
pub trait Sliced:
    Message + IntoBytes + FromBytes + Immutable + ZeroCopySend + Debug + Copy + Default + 'static
{
    /// What the slice holds.
    type Item: IntoBytes + FromBytes + Immutable + ZeroCopySend + Debug + Copy + 'static;

    /// Writes its monitoring JSON (the header, and what it says of `items`) into `out`.
    fn write_json(&self, items: &[Self::Item], rig: &str, out: &mut Vec<u8>) -> Result<()>;
}

/// What is done with a topic of each kind (opening a port, for one direction).
pub trait Visit {
    /// What it gives.
    type Out;
    /// For a topic of whole messages.
    fn whole<M: Whole>(self, topic: Topic<M>) -> Self::Out;
    /// For a topic of a header with a slice.
    fn sliced<H: Sliced>(self, topic: SliceTopic<H, H::Item>) -> Self::Out;
}

/// The table: `v` applied to topic `id` with its message type; `None` for a topic the bridge
/// does not carry (the plant's truth).
pub fn visit<V: Visit>(id: TopicId, v: V) -> Option<V::Out> {
    Some(match id {
        TopicId::JointState => v.whole(topics::JOINT_STATE),
        TopicId::ObjectPose => v.whole(topics::OBJECT_POSE),
        TopicId::GraspState => v.whole(topics::GRASP_STATE),
        TopicId::WrenchSpace => v.sliced(topics::WRENCH_SPACE),
        TopicId::PlanStep => v.sliced(topics::PLAN_STEP),
        TopicId::HandCommand => v.whole(topics::HAND_COMMAND),
        TopicId::NodeHealth => v.whole(topics::NODE_HEALTH),
        _ => return None,
    })
}

/// Serializes `value` into `out`, cleared first.
fn write(value: &impl serde::Serialize, out: &mut Vec<u8>) -> Result<()> {
    out.clear();
    serde_json::to_writer(&mut *out, value)?;
    Ok(())
}

impl Whole for JointState {
    fn write_json(&self, rig: &str, out: &mut Vec<u8>) -> Result<()> {
        write(&json::joint_state(rig, self), out)
    }
}

impl Whole for ObjectPose {
    const MONITORED: bool = false;

    fn write_json(&self, _rig: &str, _out: &mut Vec<u8>) -> Result<()> {
        Err(anyhow!("object poses are not monitored"))
    }
}

impl Whole for GraspState {
    fn write_json(&self, rig: &str, out: &mut Vec<u8>) -> Result<()> {
        write(&json::grasp_state(rig, self), out)
    }
}

impl Whole for HandCommand {
    fn write_json(&self, rig: &str, out: &mut Vec<u8>) -> Result<()> {
        write(&json::hand_command(rig, self), out)
    }
}

impl Whole for NodeHealth {
    fn write_json(&self, rig: &str, out: &mut Vec<u8>) -> Result<()> {
        write(&json::node_health(rig, self), out)
    }
}

impl Sliced for WrenchSpaceHeader {
    type Item = Facet;

    fn write_json(&self, items: &[Facet], rig: &str, out: &mut Vec<u8>) -> Result<()> {
        write(&json::wrench_space(rig, self, items.len()), out)
    }
}

impl Sliced for PlanStepHeader {
    type Item = u32;

    fn write_json(&self, _items: &[u32], rig: &str, out: &mut Vec<u8>) -> Result<()> {
        write(&json::plan_step(rig, self), out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Names the kind of each topic it is given.
    struct Kind;

    impl Visit for Kind {
        type Out = (&'static str, &'static str);
        fn whole<M: Whole>(self, topic: Topic<M>) -> Self::Out {
            (topic.name(), "whole")
        }
        fn sliced<H: Sliced>(self, topic: SliceTopic<H, H::Item>) -> Self::Out {
            (topic.name(), "sliced")
        }
    }

    #[test]
    fn the_table_carries_every_bridged_topic_under_its_own_name_and_not_the_truth() {
        for id in topics::ALL {
            let (name, kind) = visit(id, Kind).unwrap();
            assert_eq!(name, id.name());
            let slice = matches!(id, TopicId::WrenchSpace | TopicId::PlanStep);
            assert_eq!(kind, if slice { "sliced" } else { "whole" }, "{id}");
        }
        assert_eq!(visit(TopicId::PlantTruth, Kind), None);
    }
}
