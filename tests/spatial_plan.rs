//! The spatial planner on `config/allegro_sphere.toml`: the Allegro hand turns a 7 cm sphere a
//! whole turn about the hand's y axis, in space. The plan is checked from scratch: every
//! step's quality by a grasp problem built anew, every contact by forward kinematics of the
//! planned joints on the exact sphere, the joints inside their limits, the contacts inside
//! their fingertip caps, the links' capsules off the object; then `plan`, `validate` and `run`
//! through the real binary, and the configs a spatial hand refuses.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use common::{icrflow, root, scratch};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::closest_on_triangle;
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::{Space, WrenchFrame};
use icrflow_plan::planner::Phase;
use icrflow_scenario::{Config, Setup};

#[test]
fn allegro_sphere_turns_a_whole_turn_keeping_the_margin_checked_from_scratch() {
    check_from_scratch("config/allegro_sphere.toml", Vec3::y());
}

/// The ellipsoid mesh (5,040 triangles), rolled on as the polyhedron it is.
#[test]
fn allegro_ellipsoid_mesh_turns_270_degrees_about_a_tilted_axis_checked_from_scratch() {
    check_from_scratch(
        "config/allegro_ellipsoid.toml",
        Vec3::new(0.2, 1.0, 0.2).normalize(),
    );
}

/// The ellipsoid mesh as MuJoCo turns it: the plan's margin 0.12, and the gate's 0.1 kept with
/// any one contact moved to a neighbouring facet (`plan.neighbour_alpha`).
#[test]
fn allegro_ellipsoid_mesh_for_mujoco_keeps_the_gate_s_margin_a_facet_off_checked_from_scratch() {
    let name = "config/allegro_ellipsoid_mujoco.toml";
    let config = Config::load(&root().join(name)).unwrap();
    assert_eq!(config.plan.neighbour_alpha, Some(0.1));
    check_from_scratch(name, Vec3::new(0.2, 1.0, 0.2).normalize());
}

/// The sphere as MuJoCo turns it.
#[test]
fn allegro_sphere_for_mujoco_turns_a_whole_turn_keeping_the_margin_checked_from_scratch() {
    check_from_scratch("config/allegro_sphere_mujoco.toml", Vec3::y());
}

/// A smaller ellipsoid, rolled on exactly.
#[test]
fn allegro_exact_ellipsoid_turns_a_whole_turn_about_a_tilted_axis_checked_from_scratch() {
    check_from_scratch(
        "config/allegro_ellipsoid_exact.toml",
        Vec3::new(0.2, 1.0, 0.2).normalize(),
    );
}

/// Plans `name` and checks the plan from scratch: the goal, switches, the axis, every step's
/// quality recomputed where the fingertips touch (>= alpha there, and at the contacts'
/// candidates), every contact on the surface where the planned joints put the fingertip,
/// inside the fingertip cap, its candidate the facet it lies on (a polyhedron) or the nearest
/// (a smooth surface), the joints inside their limits,
/// the links' capsules off the object.
fn check_from_scratch(name: &str, axis: Vec3) {
    let config = Config::load(&root().join(name)).unwrap();
    let setup = Setup::new(&config).unwrap();
    let scenario = setup
        .spatial_scenario(&config)
        .expect("the Allegro is a spatial hand");
    let plan = scenario.plan(&mut |_| {}).unwrap();
    let s = &plan.summary;
    assert!(s.completed, "{:?}", s.stop_reason);
    assert!((s.rotation - config.plan.goal).abs() < 1e-9);
    assert!(s.rotation.to_degrees() >= 180.0 - 1e-9);
    assert!(s.switches >= 3, "{} switches", s.switches);
    // Rolling without slipping: per step, the contact travels (mm) as far over the object as
    // over the fingertip, to within 10 um (an integration that let the fingertip drift off
    // the surface and put it back slipped 6.6 mm). On a smooth surface only: on a
    // polyhedron's edges the fingertip pivots, its contact staying on the object.
    let smooth = matches!(
        scenario.surface,
        icrflow_plan::spatial::surface::Convex::Sphere { .. }
            | icrflow_plan::spatial::surface::Convex::Ellipsoid { .. }
    );
    if smooth {
        assert!(
            s.max_rolling_residual < 1e-5,
            "slip {} m",
            s.max_rolling_residual
        );
    }
    assert!((Vec3::from(s.axis) - axis).norm() < 1e-15, "{:?}", s.axis);
    // The plan's margin (`plan.alpha`: the Allegro's ellipsoid mesh keeps 0.12 over the
    // gate's 0.1).
    let alpha = config.plan.alpha;
    // A grasp problem of the same facets, built anew.
    let object = config.object.build().unwrap();
    let frame = WrenchFrame::new(object.centre_of_mass, object.max_radius(), Space::Spatial)
        .unwrap()
        .with_tangent_axis(config.turn.axis)
        .unwrap();
    let fresh = GraspProblem::new(
        &object.facets,
        object.facets.clone(),
        frame,
        config.grasp.model,
    )
    .unwrap();
    let link_radius = config.plant.link_radius;
    for step in &plan.steps {
        assert!(
            step.quality >= alpha,
            "step {}: {}",
            step.step,
            step.quality
        );
        let contacts: Vec<usize> = step.fingers.iter().filter_map(|f| f.contact).collect();
        // The margin where the fingertips touch: the grasp at the recorded points with the
        // normals the surface has there (checked below against the fingertips' poses), not
        // at their candidates.
        let touching: Vec<(Vec3, Vec3)> = step
            .fingers
            .iter()
            .filter(|f| f.contact.is_some())
            .map(|f| (Vec3::from(f.point.unwrap()), Vec3::from(f.normal.unwrap())))
            .collect();
        let e = fresh.evaluate_at(&touching).unwrap();
        assert!(e.force_closure(), "step {}", step.step);
        assert!(
            e.quality >= alpha * (1.0 - 1e-9),
            "step {}: alpha* {} where the fingertips touch < alpha = {alpha}",
            step.step,
            e.quality,
        );
        assert!(
            (e.quality - step.quality).abs() <= 1e-12,
            "step {}: {} recomputed, {} planned",
            step.step,
            e.quality,
            step.quality
        );
        // And at their candidates, what their ICRs guarantee.
        let e = fresh.evaluate(&contacts).unwrap();
        assert!(
            e.force_closure() && e.quality >= alpha * (1.0 - 1e-9),
            "step {}: alpha* {} at the candidates",
            step.step,
            e.quality
        );
        // With any one contact moved to a facet within plan.neighbour_rings of its own, the
        // grasp keeps plan.neighbour_alpha (at every step but the start, the config's).
        if let (Some(floor), false) = (config.plan.neighbour_alpha, step.phase == Phase::Start) {
            let adjacency = &object.facets.adjacency;
            for i in 0..contacts.len() {
                for n in adjacency.rings(contacts[i], config.plan.neighbour_rings) {
                    let mut moved = contacts.clone();
                    moved[i] = n as usize;
                    let e = fresh.evaluate(&moved).unwrap();
                    let q = if e.force_closure() { e.quality } else { 0.0 };
                    assert!(
                        q >= floor * (1.0 - 1e-9),
                        "step {}: contact {i} at facet {n}: {q} < {floor}",
                        step.step
                    );
                }
            }
        }
        let expected = match step.phase {
            Phase::Attach => 4,
            _ => 3,
        };
        assert_eq!(contacts.len(), expected, "step {}", step.step);
        for fs in &step.fingers {
            let f = setup.hand.finger(fs.finger).unwrap();
            assert!(
                f.limit_violation(&fs.joints, 1e-9).is_none(),
                "step {}",
                step.step
            );
            // The links' capsules stay off the sphere (centred at the hand's origin).
            let (clear, link) = scenario.link_clearance(f, &fs.joints, step.rotation);
            assert!(
                clear >= link_radius - 1e-12,
                "step {}: finger {} link {link} {clear} m from the sphere",
                step.step,
                fs.finger
            );
            let Some(c) = fs.contact else { continue };
            let (centre, cap_axis) = f.fk_tip(&fs.joints);
            // The fingertip touches the exact surface at the recorded point, with its normal:
            // the point is on the surface, and the fingertip centre a fingertip's radius out
            // along the normal has it as its closest point (on a polyhedron's edge or vertex
            // the normal is the offset surface's, between its faces'; on a smooth surface it
            // is the surface's own).
            let body = Vec3::from(fs.point.unwrap());
            let n = Vec3::from(fs.normal.unwrap());
            let on = scenario.surface.closest(&body);
            assert!(on.distance.abs() < 1e-12 && (on.point - body).norm() < 1e-12);
            let from_centre = scenario.surface.closest(&(body + n * f.tip_radius));
            assert!(
                (from_centre.point - body).norm() < 1e-9
                    && (from_centre.normal - n).norm() < 1e-9
                    && (from_centre.distance - f.tip_radius).abs() < 1e-9,
                "step {}",
                step.step
            );
            if smooth {
                assert!((on.normal - n).norm() < 1e-9);
            }
            let point = scenario.to_world(step.rotation, &body);
            let normal = scenario.to_world(step.rotation, &(n + scenario.centre));
            assert!(
                (centre - (point + normal * f.tip_radius)).norm() < 1e-9,
                "step {}",
                step.step
            );
            // Within the fingertip cap, less the margin.
            let cap = cap_axis.dot(&-normal).clamp(-1.0, 1.0).acos();
            assert!(cap <= f.cap_half_angle - config.plan.cap_margin + 1e-9);
            assert!((fs.cap_angle.unwrap() - cap).abs() < 1e-9);
            // The contact's candidate: on a smooth surface the facet whose centre is nearest
            // the point; on the polyhedron the facet the point lies on (its face's
            // triangles within 1 nm of it).
            if smooth {
                let nearest = (0..object.facets.points.len())
                    .min_by(|&a, &b| {
                        (object.facets.points[a] - body)
                            .norm()
                            .total_cmp(&(object.facets.points[b] - body).norm())
                    })
                    .unwrap();
                assert_eq!(c, nearest, "step {}", step.step);
            } else {
                let v = &object.vertices;
                let face = object.faces.face(object.facet_faces[c] as usize);
                let off = face[1..]
                    .windows(2)
                    .map(|w| {
                        let [a, b, d] = [face[0], w[0], w[1]].map(|i| v[i as usize]);
                        (closest_on_triangle(&body, &a, &b, &d) - body).norm()
                    })
                    .fold(Real::INFINITY, Real::min);
                assert!(
                    off < 1e-9,
                    "step {}: the contact is {off} m off its facet {c}",
                    step.step
                );
            }
        }
    }
    // Every switch's approach (home -> its poses -> the rendezvous point) and retreat (the
    // released contact -> its poses -> home), straight joint-space moves sampled finely: the
    // fingertip never inside the object, the links' capsules off it, the moving fingertip off
    // every other fingertip.
    for (k, step) in plan.steps.iter().enumerate() {
        let Some(w) = &step.switch else { continue };
        for (finger, vias, at) in [
            (w.attached, w.approach.as_ref().unwrap(), step),
            (w.released, w.retreat.as_ref().unwrap(), &plan.steps[k]),
        ] {
            let f = setup.hand.finger(finger).unwrap();
            let contact = &at
                .fingers
                .iter()
                .find(|x| x.finger == finger)
                .unwrap()
                .joints;
            let mut way: Vec<&[Real]> = vec![&f.home];
            way.extend(vias.iter().map(Vec::as_slice));
            way.push(contact);
            for pair in way.windows(2) {
                for i in 0..=200 {
                    let s = i as Real / 200.0;
                    let q: Vec<Real> = pair[0]
                        .iter()
                        .zip(pair[1])
                        .map(|(a, b)| a + s * (b - a))
                        .collect();
                    let tip = f.tip_centre(&q);
                    let body = scenario.to_body(step.rotation, &tip);
                    assert!(
                        scenario.surface.closest(&body).distance >= f.tip_radius - 1e-6,
                        "step {}: finger {finger}'s way passes {} m into the object",
                        step.step,
                        f.tip_radius - scenario.surface.closest(&body).distance
                    );
                    let (clear, _) = scenario.link_clearance(f, &q, step.rotation);
                    assert!(
                        clear >= link_radius - 2e-4,
                        "step {}: finger {finger}: {clear}",
                        step.step
                    );
                    for other in &step.fingers {
                        if other.finger == finger || other.contact.is_none() {
                            continue;
                        }
                        let g = setup.hand.finger(other.finger).unwrap();
                        let d = (g.tip_centre(&other.joints) - tip).norm();
                        assert!(
                            d >= f.tip_radius + g.tip_radius - 2e-4,
                            "step {}: fingers {finger} and {}",
                            step.step,
                            other.finger
                        );
                    }
                }
            }
        }
    }
    // Every finger takes part: the free finger of the start attaches somewhere.
    let attached: std::collections::BTreeSet<u32> = plan
        .steps
        .iter()
        .filter_map(|s| s.switch.as_ref().map(|w| w.attached))
        .collect();
    assert!(attached.contains(&2), "{attached:?}");
}

#[test]
fn plan_json_gains_the_axis_and_run_refuses_a_slip_off_a_sphere_by_its_key() {
    let dir = scratch("plan-spatial");
    let out = dir.join("out");
    let o = icrflow(&[
        "plan",
        "config/allegro_sphere.toml",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["completed"], true);
    assert_eq!(s["axis"], serde_json::json!([0.0, 1.0, 0.0]));
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("trajectory.json")).unwrap())
            .unwrap();
    let first = &t["steps"][0]["fingers"];
    let index = first
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["finger"] == 1)
        .unwrap();
    for key in [
        "contact",
        "point",
        "normal",
        "cap_angle_deg",
        "joints_deg",
        "tip_centre",
    ] {
        assert!(!index[key].is_null(), "finger 1 lacks {key}");
    }
    assert_eq!(index["joints_deg"].as_array().unwrap().len(), 4);
    // The planar plan's files keep their shape: no normals.
    let planar = dir.join("planar");
    let o = icrflow(&[
        "plan",
        "config/paper_sphere.toml",
        "--json",
        "--out",
        planar.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["axis"], serde_json::json!([0.0, 0.0, 1.0]));
    let text = std::fs::read_to_string(planar.join("trajectory.json")).unwrap();
    assert!(!text.contains("\"normal\""));

    let o = icrflow(&["validate", "config/allegro_sphere.toml"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("in space") && text.contains("alpha* ="),
        "{text}"
    );

    assert!(
        text.contains("the plant rolls fingertips on the exact sphere")
            && text.contains("plant      kinematic"),
        "{text}"
    );

    // The simulated slip keeps the fingertips on a sphere only: the mesh is refused by the
    // key, nothing started.
    let text = std::fs::read_to_string(root().join("config/allegro_ellipsoid.toml")).unwrap();
    let text = text
        .replace(
            "urdf = \"hands/allegro_right.urdf\"",
            &format!(
                "urdf = \"{}\"",
                root().join("config/hands/allegro_right.urdf").display()
            ),
        )
        .replace(
            "path = \"meshes",
            &format!("path = \"{}", root().join("config/meshes").display()),
        );
    let path = dir.join("refused.toml");
    std::fs::write(&path, format!("{text}\n[pipeline]\nslip_deg = 5.0\n")).unwrap();
    let o = icrflow(&["run", path.to_str().unwrap(), "--no-visualizer"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("pipeline.slip_deg") && err.contains("only for a sphere"),
        "{err}"
    );
    assert!(!err.contains("run: starting"), "{err}");
    // validate checks what run checks.
    let o = icrflow(&["validate", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("pipeline.slip_deg"), "{err}");
    // A spatial hand in MuJoCo: validate builds MuJoCo's model of the hand and the object.
    let mujoco = dir.join("mujoco.toml");
    std::fs::write(
        &mujoco,
        allegro().replace("[plant]\n", "[plant]\nkind = \"mujoco\"\n"),
    )
    .unwrap();
    let o = icrflow(&["validate", mujoco.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("plant      MuJoCo 3.17.0: the object 0.090 kg"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `config/allegro_sphere.toml`'s text with the URDF's path made absolute (for copies
/// elsewhere).
fn allegro() -> String {
    let text = std::fs::read_to_string(root().join("config/allegro_sphere.toml")).unwrap();
    let urdf = root().join("config/hands/allegro_right.urdf");
    let replaced = text.replace(
        "urdf = \"hands/allegro_right.urdf\"",
        &format!("urdf = \"{}\"", urdf.display()),
    );
    assert_ne!(replaced, text);
    replaced
}

#[test]
fn configs_a_spatial_plan_refuses_are_named_by_their_key() {
    let dir = scratch("spatial-bad");
    let allegro = allegro();
    let paper = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    let cases = [
        (
            "zero-axis",
            allegro.replace("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 0.0, 0.0]"),
            "plan.axis: [0, 0, 0] is not a direction",
        ),
        (
            "planar-axis",
            paper.replace("[plan]", "[plan]\naxis = [1.0, 0.0, 0.0]"),
            "turns objects about the hand's z axis only",
        ),
        (
            "planar-space",
            allegro.replace("space = \"spatial\"", "space = \"planar\""),
            "grasp.space",
        ),
        (
            "angle",
            allegro.replace("point = [0.0, 0.034826, 0.003483]", "angle_deg = 90.0"),
            "give point = [x, y, z]",
        ),
        (
            "not-convex",
            allegro.replace(
                "shape = \"sphere\"\nradius = 0.035\nsegments = [64, 32]",
                &format!("shape = \"mesh\"\npath = \"{}\"", l_prism(&dir).display()),
            ),
            "the mesh is not convex",
        ),
        (
            "off-surface",
            allegro.replace(
                "point = [0.0, 0.034826, 0.003483]",
                "point = [0.0, 0.05, 0.0]",
            ),
            "grasp.contacts[0].point",
        ),
    ];
    for (name, text, needle) in cases {
        assert_ne!(text, allegro, "{name}: the replacement did not apply");
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let o = icrflow(&["validate", path.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains(needle), "{name}: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// An L-shaped prism (not convex) as an OBJ file in `dir`.
fn l_prism(dir: &std::path::Path) -> std::path::PathBuf {
    let outline = [
        (0.0, 0.0),
        (2.0, 0.0),
        (2.0, 1.0),
        (1.0, 1.0),
        (1.0, 2.0),
        (0.0, 2.0),
    ];
    let mut text = String::new();
    for z in [-1.0, 1.0] {
        for (x, y) in outline {
            text += &format!("v {} {} {}\n", 0.02 * x - 0.015, 0.02 * y - 0.015, 0.02 * z);
        }
    }
    // The L's triangles (counter-clockwise seen from +z) on top, reversed below; the sides.
    for [a, b, c] in [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]] {
        text += &format!("f {} {} {}\n", a + 7, b + 7, c + 7);
        text += &format!("f {} {} {}\n", c + 1, b + 1, a + 1);
    }
    for i in 0..6 {
        let j = (i + 1) % 6;
        text += &format!("f {} {} {} {}\n", i + 1, j + 1, j + 7, i + 7);
    }
    let path = dir.join("l_prism.obj");
    std::fs::write(&path, text).unwrap();
    path
}

/// Radians inside: the summary's axis is a unit vector whatever length the config gives.
#[test]
fn the_axis_is_normalised() {
    let dir = scratch("spatial-axis");
    let allegro = allegro();
    let path = dir.join("long.toml");
    std::fs::write(
        &path,
        allegro.replace("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 3.0, 0.0]"),
    )
    .unwrap();
    let config = Config::load(&path).unwrap();
    let a: Real = config.turn.axis.norm();
    assert!((a - 1.0).abs() < 1e-15);
    assert_eq!(config.turn.axis, Vec3::y());
    let _ = std::fs::remove_dir_all(&dir);
}
