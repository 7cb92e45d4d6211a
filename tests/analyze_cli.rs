//! `icrflow analyze` end to end: the real binary on the shipped configs and on bad ones.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use common::{icrflow, root, scratch};

fn json(args: &[&str]) -> serde_json::Value {
    json_exiting(args, 0)
}

/// `analyze --json`'s object, the verb having exited with `status`.
fn json_exiting(args: &[&str], status: i32) -> serde_json::Value {
    let out = icrflow(args);
    assert_eq!(
        out.status.code(),
        Some(status),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("analyze --json prints one JSON object")
}

#[test]
fn paper_sphere_json_has_the_documented_keys_and_regions() {
    let v = json(&["analyze", "config/paper_sphere.toml", "--json"]);
    assert_eq!(v["force_closure"], true);
    assert_eq!(v["space"], "planar");
    assert_eq!(v["friction"], 0.3);
    assert_eq!(v["cone_edges"], 8);
    assert_eq!(v["alpha"], 0.1);
    let quality = v["quality"].as_f64().unwrap();
    assert!(quality > 0.1 && quality < 1.0, "alpha* = {quality}");
    assert!(v["epsilon"].as_f64().unwrap() > 0.0);
    let contacts = v["contacts"].as_array().unwrap();
    let fingers: Vec<u64> = contacts
        .iter()
        .map(|c| c["finger"].as_u64().unwrap())
        .collect();
    assert_eq!(fingers, [1, 2, 4]);
    for (c, angle) in contacts.iter().zip([30.0, 330.0, 140.0]) {
        assert!((c["angle_deg"].as_f64().unwrap() - angle).abs() < 1e-9);
        let p: Vec<f64> = c["point"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!(((p[0] * p[0] + p[1] * p[1]).sqrt() - 0.0475).abs() < 1e-12 && p[2] == 0.0);
        let points = c["icr"]["points"].as_array().unwrap();
        assert!(
            points.len() > 1,
            "finger {}: region is only the contact",
            c["finger"]
        );
        assert!(
            points
                .iter()
                .any(|q| q.as_array().unwrap() == c["point"].as_array().unwrap())
        );
        // Each region is one interval of the ring, containing the contact's angle.
        let iv = c["icr"]["angle_intervals_deg"].as_array().unwrap();
        assert_eq!(iv.len(), 1);
        let (a, b) = (iv[0][0].as_f64().unwrap(), iv[0][1].as_f64().unwrap());
        assert!((a <= angle && angle <= b) || (a <= angle + 360.0 && angle + 360.0 <= b));
        assert!(((b - a) / 5.0 + 1.0 - points.len() as f64).abs() < 1e-6);
    }
}

#[test]
fn the_papers_own_friction_is_reported_as_not_force_closure() {
    // An answer, not an error: exit status 2 (0 done, 1 error).
    let v = json_exiting(&["analyze", "config/paper_sphere_mu003.toml", "--json"], 2);
    assert_eq!(v["force_closure"], false);
    assert_eq!(v["quality"], 0.0);
    assert!(v["epsilon"].as_f64().unwrap() < 0.0);
    assert!(
        v["icr_status"]
            .as_str()
            .unwrap()
            .contains("not force closure")
    );
    for c in v["contacts"].as_array().unwrap() {
        assert!(
            c["icr"].is_null(),
            "no regions may be printed for a grasp that is not force closure"
        );
    }
    let out = icrflow(&["analyze", "config/paper_sphere_mu003.toml"]);
    assert_eq!(out.status.code(), Some(2));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("NOT force closure"), "{text}");
    assert!(text.contains("epsilon"), "{text}");
}

#[test]
fn spatial_grasp_of_a_mesh_file() {
    let dir = scratch("mesh");
    // A cube of quads, written by hand as OBJ.
    std::fs::write(
        dir.join("cube.obj"),
        "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("grasp.toml"),
        r#"
[object]
shape = "mesh"
path = "cube.obj"

[grasp]
space = "spatial"
friction = 0.5
alpha = 0.01
contacts = [
  { finger = 1, point = [1.0, 0.0, 0.0] },
  { finger = 2, point = [-1.0, 0.0, 0.0] },
  { finger = 3, point = [0.0, 1.0, 0.0] },
  { finger = 4, point = [0.0, -1.0, 0.0] },
]
"#,
    )
    .unwrap();
    let v = json(&[
        "analyze",
        dir.join("grasp.toml").to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(v["space"], "spatial");
    assert_eq!(v["facets"], 6);
    // Four face-centre contacts with friction on the side faces resist every wrench.
    assert_eq!(v["force_closure"], true, "{v}");
    for c in v["contacts"].as_array().unwrap() {
        assert!(c.get("angle_deg").is_none());
        assert!(!c["icr"]["points"].as_array().unwrap().is_empty());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_configs_fail_with_the_key_named_and_a_nonzero_exit() {
    let dir = scratch("bad");
    let good = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    let cases = [
        (
            "unknown",
            good.replace("alpha = 0.1", "alpha = 0.1\nalhpa = 0.2"),
            "alhpa",
        ),
        (
            "friction",
            good.replace("friction = 0.3", "friction = -1.0"),
            "grasp.friction",
        ),
        (
            "radius",
            good.replace("radius = 0.0475", "radius = nan"),
            "object.radius",
        ),
        (
            "mesh",
            good.replace(
                "shape = \"sphere\"\nradius = 0.0475\nsegments = [72, 72]   # longitude, latitude",
                "shape = \"mesh\"\npath = \"missing.stl\"",
            ),
            "object.path",
        ),
        ("syntax", "[object\n".to_string(), "invalid config"),
    ];
    for (name, text, needle) in cases {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let out = icrflow(&["analyze", path.to_str().unwrap()]);
        assert!(!out.status.success(), "{name}: accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(needle),
            "{name}: error does not name {needle:?}:\n{err}"
        );
        assert!(!err.contains("panicked"), "{name}: panicked:\n{err}");
    }
    // A mesh that is open is refused with the reason.
    std::fs::write(
        dir.join("open.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("open.toml"),
        good.replace(
            "shape = \"sphere\"\nradius = 0.0475\nsegments = [72, 72]   # longitude, latitude",
            "shape = \"mesh\"\npath = \"open.obj\"",
        ),
    )
    .unwrap();
    let out = icrflow(&["analyze", dir.join("open.toml").to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("open.obj") && err.to_lowercase().contains("open"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A contact given as a point is snapped to the nearest candidate and the snap printed as a
/// distance (it was printed in degrees for planar problems); a point off the surface is
/// refused with its distance, by `analyze` as by every verb.
#[test]
fn a_point_contact_snaps_by_a_distance_and_a_far_one_is_refused() {
    let dir = scratch("point");
    let good = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    // 30 deg on the 4.75 cm sphere, 0.4 mm out.
    let (x, y) = (
        0.0479 * 30f64.to_radians().cos(),
        0.0479 * 30f64.to_radians().sin(),
    );
    let near = good.replacen("angle_deg = 30.0", &format!("point = [{x}, {y}, 0.0]"), 1);
    let path = dir.join("near.toml");
    std::fs::write(&path, &near).unwrap();
    let out = icrflow(&["analyze", path.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("(candidate 6, snapped by 0.40 mm)"), "{text}");
    let v = json(&["analyze", path.to_str().unwrap(), "--json"]);
    assert!(
        (v["contacts"][0]["snap"].as_f64().unwrap() - 0.4e-3).abs() < 1e-9,
        "{v}"
    );
    let far = good.replacen("angle_deg = 30.0", "point = [1.4, 0.0, 0.0]", 1);
    let path = dir.join("far.toml");
    std::fs::write(&path, far).unwrap();
    for verb in ["analyze", "validate", "plan"] {
        let out = icrflow(&[verb, path.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{verb}: {err}");
        assert!(
            err.contains("grasp.contacts[0].point (finger 1): [1.4, 0, 0] is 1.352 m from the object's surface"),
            "{verb}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// With `plan.alpha` above `grasp.alpha`, the analysis (at the grasp's margin, the hand's
/// gate) says too whether the grasp keeps the plan's, which `validate`, `plan` and `run`
/// hold it to; without it, nothing more is said.
#[test]
fn the_plan_s_margin_is_said_where_it_keeps_more_than_the_grasp_s() {
    let dir = scratch("analyze-plan-alpha");
    let text = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    let plain = json(&["analyze", "config/paper_sphere.toml", "--json"]);
    assert!(plain.get("plan_alpha").is_none(), "{plain}");
    let quality = plain["quality"].as_f64().unwrap();
    for (plan, kept) in [(0.11, true), (0.9, false)] {
        assert_eq!(quality >= plan, kept, "alpha* {quality}");
        let path = dir.join(format!("plan_alpha_{plan}.toml"));
        std::fs::write(
            &path,
            text.replace("[plan]\n", &format!("[plan]\nalpha = {plan}\n")),
        )
        .unwrap();
        let path = path.to_str().unwrap();
        // The grasp keeps the hand's margin either way: analyze succeeds.
        let v = json(&["analyze", path, "--json"]);
        assert_eq!(v["alpha"], 0.1);
        assert_eq!(v["plan_alpha"], plan);
        let out = icrflow(&["analyze", path]);
        assert_eq!(out.status.code(), Some(0));
        let said = String::from_utf8_lossy(&out.stdout);
        let line = format!(
            "{} plan.alpha = {plan}, the plan's margin over the hand's: validate, plan and run {}",
            if kept { ">=" } else { "<" },
            if kept { "take it" } else { "refuse it" }
        );
        assert!(said.contains(&line), "{said}");
        // As validate has it.
        let checked = icrflow(&["validate", path]);
        assert_eq!(
            checked.status.success(),
            kept,
            "{}",
            String::from_utf8_lossy(&checked.stderr)
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
