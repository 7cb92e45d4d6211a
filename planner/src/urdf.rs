//! Hands from URDF files (through the `urdf-rs` crate).
//!
//! Each finger is named by its fingertip link: the chain is every joint from the URDF's root
//! link down to that link. Revolute joints become [`Joint`]s (continuous joints get limits of
//! +-180 deg); fixed joints are folded into the neighbouring transforms; any other joint type
//! is an error naming it. The fingertip centre is the origin of the fingertip link, and its
//! radius is the radius of that link's sphere collision geometry unless the caller gives one.
//!
//! The file is checked to be one tree first ([`check_tree`]): every joint's parent and child
//! links declared, each link the child of at most one joint, one root, no cycle. Fingers may
//! share fixed joints (a palm's mount) but no revolute one.

use std::f64::consts::PI;
use std::path::Path;

use icrflow_grasp::math::{Isometry3, Real, UnitQuaternion, Vec3};
use nalgebra::{Translation3, Unit};

use crate::hand::{Finger, HandError, Joint};

/// How one finger is taken from the URDF.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfFinger {
    /// Finger number.
    pub id: u32,
    /// Name of the fingertip link (its origin is the fingertip sphere's centre).
    pub tip_link: String,
    /// Fingertip radius; `None`: the tip link's sphere collision radius.
    pub tip_radius: Option<Real>,
    /// Cap half-angle (rad).
    pub cap_half_angle: Real,
    /// Home joint angles; `None`: zero clamped into the limits.
    pub home: Option<Vec<Real>>,
}

/// Reads a URDF file and builds the named fingers, with the URDF's root placed at `root` in
/// the hand frame.
pub fn fingers_from_file(
    path: &Path,
    root: Isometry3,
    fingers: &[UrdfFinger],
) -> Result<Vec<Finger>, HandError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| HandError::Urdf(format!("cannot read {}: {e}", path.display())))?;
    fingers_from_str(&text, root, fingers)
        .map_err(|e| HandError::Urdf(format!("{}: {e}", path.display())))
}

/// As [`fingers_from_file`], from URDF text.
pub fn fingers_from_str(
    text: &str,
    root: Isometry3,
    fingers: &[UrdfFinger],
) -> Result<Vec<Finger>, HandError> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| HandError::Urdf(e.to_string()))?;
    check_tree(&robot)?;
    let built = fingers
        .iter()
        .map(|spec| finger(&robot, root, spec))
        .collect::<Result<Vec<_>, _>>()?;
    // Each finger's joints are its own: the hand commands them finger by finger.
    for (i, a) in built.iter().enumerate() {
        for b in &built[i + 1..] {
            if let Some(j) = a
                .joints
                .iter()
                .find(|j| b.joints.iter().any(|k| k.name == j.name))
            {
                return Err(HandError::Invalid {
                    finger: b.id,
                    what: format!(
                        "shares joint {:?} with finger {} (the chains from the URDF's root to {:?} and {:?}): each finger's joints must be its own",
                        j.name,
                        a.id,
                        spec_of(fingers, a.id),
                        spec_of(fingers, b.id)
                    ),
                });
            }
        }
    }
    Ok(built)
}

fn spec_of(fingers: &[UrdfFinger], id: u32) -> &str {
    fingers
        .iter()
        .find(|f| f.id == id)
        .map_or("", |f| f.tip_link.as_str())
}

/// Checks that the URDF is one tree: links and joints named once each, every joint's parent
/// and child links declared, every link the child of at most one joint, one root link, and
/// every link reachable from it (so no cycle).
pub fn check_tree(robot: &urdf_rs::Robot) -> Result<(), HandError> {
    use std::collections::{BTreeMap, BTreeSet};
    let bad = |what: String| Err(HandError::Urdf(what));
    if robot.links.is_empty() {
        return bad("it declares no link".into());
    }
    let mut links = BTreeSet::new();
    for l in &robot.links {
        if !links.insert(l.name.as_str()) {
            return bad(format!("link {:?} is declared twice", l.name));
        }
    }
    let mut names = BTreeSet::new();
    // Each link's parent joint.
    let mut parent: BTreeMap<&str, &urdf_rs::Joint> = BTreeMap::new();
    for j in &robot.joints {
        if !names.insert(j.name.as_str()) {
            return bad(format!("joint {:?} is declared twice", j.name));
        }
        for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains(link.as_str()) {
                return bad(format!(
                    "joint {:?}: its {role} link {link:?} is not declared (no <link name={link:?}>)",
                    j.name
                ));
            }
        }
        if j.parent.link == j.child.link {
            return bad(format!(
                "joint {:?} joins link {:?} to itself (a cycle)",
                j.name, j.child.link
            ));
        }
        if let Some(other) = parent.insert(j.child.link.as_str(), j) {
            return bad(format!(
                "link {:?} is the child of two joints, {:?} and {:?}: a URDF is a tree, each link with one parent",
                j.child.link, other.name, j.name
            ));
        }
    }
    let roots: Vec<&str> = robot
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|l| !parent.contains_key(l))
        .collect();
    // Every link has a parent: they all lie on cycles.
    let Some(&root) = roots.first() else {
        return bad(format!(
            "the joints form a cycle: every link is some joint's child, so there is no root (joints {:?})",
            robot
                .joints
                .iter()
                .map(|j| j.name.as_str())
                .collect::<Vec<_>>()
        ));
    };
    if roots.len() > 1 {
        return bad(format!(
            "not one connected tree: {} links are roots (no joint has them as its child): {:?}",
            roots.len(),
            roots
        ));
    }
    // One root, and each other link with one parent: a link whose ancestors never reach the
    // root lies on (or hangs from) a cycle.
    for l in &robot.links {
        let mut at = l.name.as_str();
        let mut path = Vec::new();
        while at != root {
            // Every link but the root has a parent (there is one root).
            let Some(&j) = parent.get(at) else { break };
            if path.contains(&j.name.as_str()) {
                return bad(format!(
                    "the joints {path:?} form a cycle, cut off from the root link {root:?}"
                ));
            }
            path.push(j.name.as_str());
            at = j.parent.link.as_str();
        }
    }
    Ok(())
}

fn pose(p: &urdf_rs::Pose) -> Isometry3 {
    let [r, pi, y] = p.rpy.0;
    Isometry3::from_parts(
        Translation3::new(p.xyz.0[0], p.xyz.0[1], p.xyz.0[2]),
        UnitQuaternion::from_euler_angles(r, pi, y),
    )
}

fn finger(robot: &urdf_rs::Robot, root: Isometry3, spec: &UrdfFinger) -> Result<Finger, HandError> {
    let bad = |what: String| HandError::Invalid {
        finger: spec.id,
        what,
    };
    let tip = robot
        .links
        .iter()
        .find(|l| l.name == spec.tip_link)
        .ok_or_else(|| bad(format!("URDF has no link named {:?}", spec.tip_link)))?;
    // Walk up from the tip to the root (the tree is checked: this ends).
    let mut chain: Vec<&urdf_rs::Joint> = Vec::new();
    let mut link = spec.tip_link.as_str();
    while let Some(j) = robot.joints.iter().find(|j| j.child.link == link) {
        if chain.len() > robot.joints.len() {
            return Err(bad("the URDF's joints form a cycle".into()));
        }
        chain.push(j);
        link = &j.parent.link;
    }
    if chain.is_empty() {
        return Err(bad(format!(
            "tip link {:?} is the URDF's root: no joint leads to it",
            spec.tip_link
        )));
    }
    chain.reverse();
    let mut joints = Vec::new();
    // Fixed transform accumulated since the last revolute joint.
    let mut pending = Isometry3::identity();
    for j in chain {
        let origin = pose(&j.origin);
        match j.joint_type {
            urdf_rs::JointType::Fixed => pending *= origin,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                let axis = Vec3::from(j.axis.xyz.0);
                let axis = Unit::try_new(axis, 1e-12)
                    .ok_or_else(|| bad(format!("joint {:?} has a zero axis", j.name)))?;
                let (lower, upper) = if j.joint_type == urdf_rs::JointType::Continuous {
                    (-PI, PI)
                } else {
                    (j.limit.lower, j.limit.upper)
                };
                joints.push(Joint {
                    name: j.name.clone(),
                    origin: pending * origin,
                    axis,
                    lower,
                    upper,
                });
                pending = Isometry3::identity();
            }
            ref other => {
                return Err(bad(format!(
                    "joint {:?} is {other:?}: only revolute, continuous and fixed joints are supported",
                    j.name
                )));
            }
        }
    }
    if pending.rotation.angle() > 1e-12 && joints.is_empty() {
        return Err(bad(format!(
            "no revolute joint between the root and {:?}",
            spec.tip_link
        )));
    }
    let radius = match spec.tip_radius {
        Some(r) => r,
        None => tip
            .collision
            .iter()
            .find_map(|c| match c.geometry {
                urdf_rs::Geometry::Sphere { radius } => Some(radius),
                _ => None,
            })
            .ok_or_else(|| {
                bad(format!(
                    "link {:?} has no sphere collision geometry: give the fingertip radius",
                    spec.tip_link
                ))
            })?,
    };
    Finger::new(
        spec.id,
        root,
        joints,
        pending.translation.vector,
        radius,
        spec.cap_half_angle,
        spec.home.clone(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn robot(body: &str) -> urdf_rs::Robot {
        urdf_rs::read_from_string(&format!("<robot name=\"r\">{body}</robot>")).unwrap()
    }

    fn joint(name: &str, parent: &str, child: &str) -> String {
        format!(
            "<joint name=\"{name}\" type=\"fixed\"><parent link=\"{parent}\"/><child link=\"{child}\"/></joint>"
        )
    }

    fn links(names: &[&str]) -> String {
        names
            .iter()
            .map(|n| format!("<link name=\"{n}\"/>"))
            .collect()
    }

    fn fault(body: &str) -> String {
        check_tree(&robot(body)).unwrap_err().to_string()
    }

    #[test]
    fn a_urdf_must_be_one_tree() {
        let tree = links(&["palm", "a", "b"]) + &joint("ja", "palm", "a") + &joint("jb", "a", "b");
        check_tree(&robot(&tree)).unwrap();
        let e =
            fault(&(links(&["palm", "a"]) + &joint("ja", "palm", "a") + &joint("jb", "a", "b")));
        assert!(
            e.contains("joint \"jb\": its child link \"b\" is not declared"),
            "{e}"
        );
        let e = fault(&(links(&["palm", "a"]) + &joint("ja", "hand", "a")));
        assert!(
            e.contains("its parent link \"hand\" is not declared"),
            "{e}"
        );
        let e = fault(&(links(&["palm", "a", "b"]) + &joint("ja", "palm", "a")));
        assert!(
            e.contains("not one connected tree") && e.contains("\"b\""),
            "{e}"
        );
        let e = fault(
            &(links(&["palm", "a", "b"])
                + &joint("ja", "palm", "a")
                + &joint("jb", "a", "b")
                + &joint("jc", "palm", "b")),
        );
        assert!(e.contains("link \"b\" is the child of two joints"), "{e}");
        let e = fault(&(links(&["a", "b"]) + &joint("ja", "a", "b") + &joint("jb", "b", "a")));
        assert!(e.contains("cycle"), "{e}");
        let e =
            fault(&(links(&["palm", "a", "b"]) + &joint("ja", "a", "b") + &joint("jb", "b", "a")));
        assert!(
            e.contains("form a cycle, cut off from the root link \"palm\""),
            "{e}"
        );
        let e = fault(&(links(&["palm", "a"]) + &joint("ja", "a", "a")));
        assert!(e.contains("joins link \"a\" to itself"), "{e}");
        let e = fault(&(links(&["palm", "palm"])));
        assert!(e.contains("link \"palm\" is declared twice"), "{e}");
    }
}
