//! The MJCF model of a hand holding an object: what [`crate::sim::Sim`] compiles in MuJoCo.
//!
//! - **The hand** from its kinematic chains ([`Finger`]): per finger a nested body per revolute
//!   joint (the body placed at the joint's origin, the hinge at the body's origin about the
//!   joint's axis, its limits as the joint's range), so MuJoCo's forward kinematics are ours;
//!   each link a capsule of [`Params::link_radius`] from its joint to the next (the distal link
//!   to where it enters the fingertip), the fingertip a sphere of the finger's radius. The hand
//!   frame is MuJoCo's world frame; the palm is fixed in it.
//! - **Actuators**: a position servo per joint (`kp`, `kv`), the joint's range as its control
//!   range. The fingertip force targets reach the joints as feed-forward torques `J^T f`
//!   ([`crate::sim::Sim`] writes them into `qfrc_applied` every step).
//! - **The object**: a free body whose frame is the object's body frame (at the hand frame's
//!   origin at the start), its geometry exact for spheres and ellipsoids and the mesh's
//!   triangles otherwise (MuJoCo collides with a mesh's convex hull: exact for the convex
//!   objects the planner rolls on), its mass and inertia from the solid at
//!   [`Params::density`].
//! - **Contacts**: fingertips and links collide with the object and with the other fingers'
//!   fingertips and links, never with their own finger ([`collision_bits`]: a bit per finger
//!   in `contype`, the object's bit and every other finger's in `conaffinity`), so that a plan
//!   whose fingers touch each other or whose links touch the object shows it
//!   ([`crate::sim::Collisions`]); friction `mu` on both sides (MuJoCo takes the larger),
//!   three-dimensional (sliding friction, no torsional or rolling resistance: a fingertip
//!   rolls freely), elliptic
//!   cones with `impratio` 10 (stiff friction) and [`Params::noslip_iterations`] of the
//!   no-slip solver (without it, friction under a steady tangential load creeps), stiff
//!   contacts (`solref`
//!   [`CONTACT_TIME_CONSTANT`]).
//! - **Solver**: `implicitfast` integration (stable with the servos' damping), the timestep
//!   [`Params::timestep`], gravity [`Params::gravity`].

use std::fmt::Write as _;

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_plan::hand::Hand;
use icrflow_plan::planner::Contact;

/// Time constant of the contacts' spring-damper (s; critically damped): stiff, so that a few
/// newtons press a fingertip a fraction of a millimetre into the object. MuJoCo needs it at
/// least twice the timestep ([`Params::timestep`] is bounded accordingly).
pub const CONTACT_TIME_CONSTANT: Real = 0.005;
/// Joint armature (kg m^2): rotor inertia, which keeps the light links' dynamics stable at
/// millisecond timesteps.
pub const ARMATURE: Real = 2e-4;
/// Density of the links and fingertips (kg/m^3).
pub const HAND_DENSITY: Real = 1000.0;

/// The object's geometry as MuJoCo has it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A sphere about the body frame's origin (m).
    Sphere {
        /// Radius (m).
        radius: Real,
    },
    /// An ellipsoid about the body frame's origin, axes along the frame's.
    Ellipsoid {
        /// Semi-axes (m).
        semi_axes: [Real; 3],
    },
    /// The object's mesh (its faces triangulated).
    Mesh,
}

/// The physical settings of the model (the `[plant]` section).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    /// Integration timestep (s).
    pub timestep: Real,
    /// Gravity in the hand frame (m/s^2).
    pub gravity: Vec3,
    /// The object's density (kg/m^3).
    pub density: Real,
    /// Friction coefficient of every contact.
    pub friction: Real,
    /// Radius of the links' capsules (m).
    pub link_radius: Real,
    /// Position gain of the joint servos (N m / rad).
    pub kp: Real,
    /// Velocity gain of the joint servos (N m s / rad).
    pub kv: Real,
    /// Iterations of MuJoCo's no-slip solver after each step (0: none).
    pub noslip_iterations: u32,
}

/// Why a model cannot be written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// A value MuJoCo cannot take (named, with why).
    #[error("{0}")]
    Invalid(String),
}

/// Names in the model: `f<id>_b<k>` bodies, `f<id>_j<k>` joints and `f<id>_a<k>` actuators
/// (k from 1, palm out), `f<id>_tip` the fingertip geom, `object` the object's body and geom.
pub fn joint_name(finger: u32, k: usize) -> String {
    format!("f{finger}_j{}", k + 1)
}

/// The fingertip geom's name of finger `finger`.
pub fn tip_name(finger: u32) -> String {
    format!("f{finger}_tip")
}

/// The actuator's name of joint `k` (from 0) of finger `finger`.
pub fn actuator_name(finger: u32, k: usize) -> String {
    format!("f{finger}_a{}", k + 1)
}

/// The object's body and geom name.
pub const OBJECT: &str = "object";

/// The most fingers a model can have: a `contype` bit each, besides the object's.
pub const MAX_FINGERS: usize = 31;

/// `(contype, conaffinity)` of the geoms of the finger in `slot` of `fingers`, and of the
/// object (`slot == fingers`): MuJoCo makes a contact between two geoms when either's
/// `contype` shares a bit with the other's `conaffinity`. The object has bit 0, the finger in
/// slot `k` bit `k + 1`; a finger's affinity is the object's bit and every other finger's, the
/// object's every finger's: fingers touch the object and each other, never themselves (its
/// adjacent links, which share a joint, would touch at every pose).
pub fn collision_bits(slot: usize, fingers: usize) -> (u32, u32) {
    let all = ((1u64 << (fingers + 1)) - 2) as u32;
    if slot >= fingers {
        (1, all)
    } else {
        let own = 1u32 << (slot + 1);
        (own, 1 | (all & !own))
    }
}

/// `x y z` with enough digits to round-trip.
fn v3(out: &mut String, v: &Vec3) {
    let _ = write!(out, "{:e} {:e} {:e}", v.x, v.y, v.z);
}

/// `w x y z` of a unit quaternion.
fn quat(out: &mut String, q: &nalgebra::UnitQuaternion<Real>) {
    let q = q.quaternion();
    let _ = write!(out, "{:e} {:e} {:e} {:e}", q.w, q.i, q.j, q.k);
}

/// Every finger's joints in the initial grasp `contacts` (a free finger at its home pose).
pub fn initial_joints(hand: &Hand, contacts: &[Contact]) -> Vec<Vec<Real>> {
    hand.fingers
        .iter()
        .map(|f| {
            contacts
                .iter()
                .find(|c| c.finger == f.id)
                .map_or_else(|| f.home.clone(), |c| c.q.clone())
        })
        .collect()
}

/// The MJCF of `hand` holding `object` (geometry `shape`) under `p`.
pub fn mjcf(hand: &Hand, object: &Object, shape: Shape, p: &Params) -> Result<String, SceneError> {
    let bad = |what: String| Err(SceneError::Invalid(what));
    if !(p.timestep > 0.0 && 2.0 * p.timestep <= CONTACT_TIME_CONSTANT) {
        return bad(format!(
            "the timestep {} ms must be positive and at most half the contacts' time constant ({} ms)",
            p.timestep * 1e3,
            CONTACT_TIME_CONSTANT * 1e3
        ));
    }
    for (what, x) in [
        ("density", p.density),
        ("friction", p.friction),
        ("link radius", p.link_radius),
        ("kp", p.kp),
    ] {
        if !(x.is_finite() && x > 0.0) {
            return bad(format!("the {what} must be finite and positive, got {x}"));
        }
    }
    if !(p.kv.is_finite() && p.kv >= 0.0 && p.gravity.iter().all(|g| g.is_finite())) {
        return bad("kv must be finite and >= 0, gravity finite".into());
    }
    let n = hand.fingers.len();
    if n > MAX_FINGERS {
        return bad(format!(
            "the hand has {n} fingers: the model takes at most {MAX_FINGERS} (a collision bit each)"
        ));
    }
    let mut x = String::with_capacity(4096 + 64 * object.vertices.len());
    x.push_str("<mujoco model=\"icrflow\">\n");
    x.push_str("  <compiler angle=\"radian\" autolimits=\"true\" boundmass=\"1e-6\" boundinertia=\"1e-12\"/>\n");
    let _ = write!(
        x,
        "  <option timestep=\"{:e}\" integrator=\"implicitfast\" cone=\"elliptic\" impratio=\"10\" noslip_iterations=\"{}\" gravity=\"",
        p.timestep, p.noslip_iterations
    );
    v3(&mut x, &p.gravity);
    x.push_str("\"/>\n");
    let _ = writeln!(
        x,
        "  <default>\n    <geom condim=\"3\" friction=\"{mu:e} 0 0\" solref=\"{tc:e} 1\" solimp=\"0.95 0.99 0.0005\"/>\n    <joint armature=\"{ARMATURE:e}\" damping=\"0\"/>\n  </default>",
        mu = p.friction,
        tc = CONTACT_TIME_CONSTANT,
    );
    if shape == Shape::Mesh {
        mesh_asset(&mut x, object)?;
    }
    x.push_str("  <worldbody>\n");
    // The object: a free body at the hand frame's origin.
    let _ = write!(
        x,
        "    <body name=\"{OBJECT}\">\n      <freejoint name=\"{OBJECT}\"/>\n"
    );
    let (object_type, object_affinity) = collision_bits(n, n);
    let _ = write!(
        x,
        "      <geom name=\"{OBJECT}\" contype=\"{object_type}\" conaffinity=\"{object_affinity}\" density=\"{:e}\" rgba=\"0.85 0.55 0.25 1\" ",
        p.density
    );
    match shape {
        Shape::Sphere { radius } => {
            let _ = write!(x, "type=\"sphere\" size=\"{radius:e}\"");
        }
        Shape::Ellipsoid {
            semi_axes: [a, b, c],
        } => {
            let _ = write!(x, "type=\"ellipsoid\" size=\"{a:e} {b:e} {c:e}\"");
        }
        Shape::Mesh => {
            let _ = write!(x, "type=\"mesh\" mesh=\"{OBJECT}\"");
        }
    }
    x.push_str("/>\n    </body>\n");
    // The fingers.
    for (slot, f) in hand.fingers.iter().enumerate() {
        let (contype, conaffinity) = collision_bits(slot, n);
        let mut depth = 0;
        for (k, j) in f.joints.iter().enumerate() {
            let origin = if k == 0 { f.base * j.origin } else { j.origin };
            let indent = "  ".repeat(2 + depth);
            let _ = write!(x, "{indent}<body name=\"f{}_b{}\" pos=\"", f.id, k + 1);
            v3(&mut x, &origin.translation.vector);
            x.push_str("\" quat=\"");
            quat(&mut x, &origin.rotation);
            x.push_str("\">\n");
            let _ = write!(
                x,
                "{indent}  <joint name=\"{}\" type=\"hinge\" axis=\"",
                joint_name(f.id, k)
            );
            v3(&mut x, &j.axis);
            let _ = writeln!(x, "\" range=\"{:e} {:e}\"/>", j.lower, j.upper);
            // The link to the next joint, or to where it enters the fingertip.
            let (to, last) = match f.joints.get(k + 1) {
                Some(next) => (next.origin.translation.vector, false),
                None => {
                    let length = f.tip.norm();
                    let inside = length - f.tip_radius;
                    (f.tip * (inside.max(0.0) / length), true)
                }
            };
            if to.norm() > 1e-6 {
                let _ = write!(
                    x,
                    "{indent}  <geom type=\"capsule\" size=\"{:e}\" fromto=\"0 0 0 ",
                    p.link_radius
                );
                v3(&mut x, &to);
                let _ = writeln!(
                    x,
                    "\" contype=\"{contype}\" conaffinity=\"{conaffinity}\" density=\"{HAND_DENSITY:e}\" rgba=\"0.55 0.6 0.7 1\"/>"
                );
            }
            if last {
                let _ = write!(
                    x,
                    "{indent}  <geom name=\"{}\" type=\"sphere\" size=\"{:e}\" pos=\"",
                    tip_name(f.id),
                    f.tip_radius
                );
                v3(&mut x, &f.tip);
                let _ = writeln!(
                    x,
                    "\" contype=\"{contype}\" conaffinity=\"{conaffinity}\" density=\"{HAND_DENSITY:e}\" rgba=\"0.3 0.45 0.8 1\"/>"
                );
            }
            depth += 1;
        }
        for d in (0..depth).rev() {
            let _ = writeln!(x, "{}</body>", "  ".repeat(2 + d));
        }
    }
    x.push_str("  </worldbody>\n  <actuator>\n");
    for f in &hand.fingers {
        for (k, j) in f.joints.iter().enumerate() {
            let _ = writeln!(
                x,
                "    <position name=\"{}\" joint=\"{}\" kp=\"{:e}\" kv=\"{:e}\" ctrlrange=\"{:e} {:e}\"/>",
                actuator_name(f.id, k),
                joint_name(f.id, k),
                p.kp,
                p.kv,
                j.lower,
                j.upper
            );
        }
    }
    x.push_str("  </actuator>\n</mujoco>\n");
    Ok(x)
}

/// The object's mesh as an MJCF asset, its polygons fanned into triangles.
fn mesh_asset(x: &mut String, object: &Object) -> Result<(), SceneError> {
    if object.vertices.len() < 4 {
        return Err(SceneError::Invalid(format!(
            "the object's mesh has {} vertices: MuJoCo needs at least 4",
            object.vertices.len()
        )));
    }
    let _ = write!(x, "  <asset>\n    <mesh name=\"{OBJECT}\" vertex=\"");
    for (i, v) in object.vertices.iter().enumerate() {
        if i > 0 {
            x.push(' ');
        }
        v3(x, v);
    }
    x.push_str("\" face=\"");
    let mut first = true;
    for face in object.faces.iter() {
        for k in 1..face.len().saturating_sub(1) {
            if !first {
                x.push(' ');
            }
            first = false;
            let _ = write!(x, "{} {} {}", face[0], face[k], face[k + 1]);
        }
    }
    x.push_str("\"/>\n  </asset>\n");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn params() -> Params {
        Params {
            timestep: 5e-4,
            gravity: Vec3::zeros(),
            density: 500.0,
            friction: 0.3,
            link_radius: 0.004,
            kp: 5.0,
            kv: 0.05,
            noslip_iterations: 0,
        }
    }

    #[test]
    fn the_paper_hand_is_four_chains_of_three_hinges_with_a_fingertip_each() {
        let hand = icrflow_plan::paper::hand();
        let object = Object::sphere(0.0475, 16, 16).unwrap();
        let xml = mjcf(&hand, &object, Shape::Sphere { radius: 0.0475 }, &params()).unwrap();
        assert_eq!(xml.matches("type=\"hinge\"").count(), 12);
        assert_eq!(xml.matches("<position ").count(), 12);
        for f in 1..=4 {
            assert_eq!(
                xml.matches(&format!("name=\"f{f}_tip\"")).count(),
                1,
                "{xml}"
            );
        }
        assert_eq!(xml.matches("<freejoint").count(), 1);
        assert!(xml.contains("type=\"sphere\" size=\"4.75e-2\""), "{xml}");
        // Bodies nest: every opened body is closed.
        assert_eq!(xml.matches("<body").count(), xml.matches("</body>").count());
    }

    #[test]
    fn fingers_touch_the_object_and_each_other_never_themselves() {
        // MuJoCo's rule: a contact when either's contype meets the other's conaffinity.
        let touch = |a: (u32, u32), b: (u32, u32)| a.0 & b.1 != 0 || b.0 & a.1 != 0;
        for n in [1, 4, 5, MAX_FINGERS] {
            let object = collision_bits(n, n);
            for i in 0..n {
                let fi = collision_bits(i, n);
                assert!(touch(fi, object), "finger {i} of {n} and the object");
                assert!(!touch(fi, fi), "finger {i} of {n} and itself");
                for j in (0..n).filter(|&j| j != i) {
                    assert!(touch(fi, collision_bits(j, n)), "fingers {i}, {j} of {n}");
                }
            }
        }
        let hand = icrflow_plan::paper::hand();
        let object = Object::sphere(0.0475, 16, 16).unwrap();
        let xml = mjcf(&hand, &object, Shape::Sphere { radius: 0.0475 }, &params()).unwrap();
        // Finger 1 (slot 0): bit 1; touches the object (bit 0) and fingers 2-4 (bits 2-4).
        assert!(xml.contains("contype=\"2\" conaffinity=\"29\""), "{xml}");
        assert!(xml.contains("contype=\"1\" conaffinity=\"30\""), "{xml}");
    }

    #[test]
    fn bad_physical_values_are_named() {
        let hand = icrflow_plan::paper::hand();
        let object = Object::sphere(0.0475, 16, 16).unwrap();
        let sphere = Shape::Sphere { radius: 0.0475 };
        let mut p = params();
        p.timestep = 0.004;
        let e = mjcf(&hand, &object, sphere, &p).unwrap_err().to_string();
        assert!(e.contains("timestep 4 ms"), "{e}");
        let mut p = params();
        p.density = -1.0;
        let e = mjcf(&hand, &object, sphere, &p).unwrap_err().to_string();
        assert!(e.contains("density"), "{e}");
    }
}
