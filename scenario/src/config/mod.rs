//! Configuration: parsed from TOML in two steps, raw serde structs that reject unknown keys
//! ([`raw`](crate::raw)), then this validated, typed config, whose [`Config::load`] is the only
//! way in. Every error names the offending key. One file per section, as the raw structs are:
//! [`object`], [`grasp`], [`hand`], [`plan`], [`pipeline`], [`plant`], [`zenoh`],
//! [`visualizer`]. The keys are documented in `docs/configuration.md`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::Real;
use icrflow_grasp::wrench::Space;
use icrflow_plan::planner::Settings;

use crate::bounds::{Range, num};
use crate::raw::RawConfig;

mod grasp;
mod hand;
mod object;
mod pipeline;
mod plan;
mod plant;
mod visualizer;
mod zenoh;

pub use grasp::*;
pub use hand::*;
pub use object::*;
pub use pipeline::*;
pub use plan::*;
pub use plant::*;
pub use visualizer::*;
pub use zenoh::*;

/// A validated config.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// The file it came from.
    pub path: PathBuf,
    /// The object.
    pub object: ObjectSpec,
    /// The grasp.
    pub grasp: GraspSpec,
    /// The hand.
    pub hand: HandSpec,
    /// Planner settings (alpha from `[grasp]`).
    pub plan: Settings,
    /// The `[plan]` keys of the spatial planner: the axis the object turns about.
    pub turn: Turn,
    /// Keys given that only one kind of hand's planning reads, refused for the other kind by
    /// [`Setup::new`](crate::Setup::new) (whether a hand is planar or spatial is known once
    /// it is built).
    pub hand_keys: HandKeys,
    /// Pipeline settings.
    pub pipeline: PipelineSpec,
    /// What the plant simulates.
    pub plant: PlantSpec,
    /// The Zenoh bridge.
    pub zenoh: ZenohSpec,
    /// The Rerun visualizer.
    pub visualizer: VisualizerSpec,
}

impl Config {
    /// Reads, parses and validates a config file. Relative paths in it are resolved against
    /// the file's directory.
    pub fn load(path: &Path) -> Result<Self> {
        if path.is_dir() {
            bail!(
                "cannot read config {}: it is a directory, not a file",
                path.display()
            );
        }
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read config {}", path.display()))?;
        Self::parse(&text, path).with_context(|| format!("invalid config {}", path.display()))
    }

    /// Parses and validates config text; `path` locates relative file names.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let raw: RawConfig = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        Self::from_raw(raw, path)
    }

    /// Validates a config given as a TOML table, shaped like the file (built in code, e.g.
    /// by the Python package from a dict); `path` locates relative file names as for
    /// [`Config::parse`] (a name in the directory they are relative to).
    pub fn from_table(table: toml::Table, path: &Path) -> Result<Self> {
        let raw: RawConfig = table.try_into().map_err(|e| anyhow::anyhow!("{e}"))?;
        Self::from_raw(raw, path)
    }

    fn from_raw(raw: RawConfig, path: &Path) -> Result<Self> {
        let base = path.parent().unwrap_or(Path::new("."));
        let grasp = grasp_spec(raw.grasp)?;
        let hand = match raw.hand {
            None => HandSpec::Paper,
            Some(h) => hand_spec(h, base)?,
        };
        let turn = turn_spec(raw.plan.as_ref())?;
        let link_radius = raw
            .plant
            .as_ref()
            .is_some_and(|p| p.link_radius_mm.is_some() && p.kind.as_deref() != Some("mujoco"));
        let hand_keys = hand_keys(raw.plan.as_ref(), link_radius);
        let plan = plan_spec(raw.plan, grasp.alpha)?;
        if let Some(a) = plan.neighbour_alpha {
            if grasp.space == Space::Planar {
                bail!(
                    "plan.neighbour_alpha: the spatial planner's check (grasp.space = \"spatial\"); the planar planner keeps its contacts off the regions' edges by plan.region_erosion"
                );
            }
            if a > plan.alpha {
                bail!(
                    "plan.neighbour_alpha: {} is above the plan's margin {} (plan.alpha, or grasp.alpha): the grasps a contact's neighbours make are held to at most the plan's own",
                    num(a),
                    num(plan.alpha)
                );
            }
        }
        let pipeline = pipeline_spec(raw.pipeline.unwrap_or_default())?;
        let plant = plant_spec(raw.plant.unwrap_or_default())?;
        if plant.kind != PlantKind::Mujoco && pipeline.push.is_some() {
            bail!(
                "pipeline.push_n / push_nm: a push of the object in MuJoCo needs plant.kind = \"mujoco\" (the kinematic plant's disturbance is pipeline.slip_deg)"
            );
        }
        if plant.kind == PlantKind::Mujoco && pipeline.slip != 0.0 {
            bail!(
                "pipeline.slip_deg: the kinematic plant's scripted slip; with plant.kind = \"mujoco\" the physics slips by itself (leave slip_deg out)"
            );
        }
        let zenoh = zenoh_spec(raw.zenoh.unwrap_or_default(), base)?;
        let visualizer = visualizer_spec(raw.visualizer.unwrap_or_default(), path)?;
        if pipeline.split() {
            if !zenoh.enabled {
                bail!(
                    "pipeline.nodes: the other nodes' topics cross over Zenoh, so zenoh.enabled must be true"
                );
            }
            if zenoh.users_file.is_some() && zenoh.link_users.is_empty() && zenoh.read_only {
                bail!(
                    "zenoh.link_users: name the users the other hosts log in as (with zenoh.users_file, only they may put the loop topics this host takes)"
                );
            }
        }
        Ok(Self {
            path: path.to_path_buf(),
            object: object_spec(raw.object, base)?,
            grasp,
            hand,
            plan,
            turn,
            hand_keys,
            pipeline,
            plant,
            zenoh,
            visualizer,
        })
    }
}

/// Each of `values` in `range`, keys `key[0]`, `key[1]`, ...
pub(crate) fn each<const N: usize>(
    key: &str,
    values: [Real; N],
    range: Range,
) -> Result<[Real; N]> {
    for (i, x) in values.iter().enumerate() {
        range.check(&format!("{key}[{i}]"), *x)?;
    }
    Ok(values)
}

/// A vector key's components: exactly `N` of them (`what` says which, e.g. `[x, y, z] (m)`),
/// else an error naming the key, the count given and the count expected.
pub(crate) fn components<const N: usize>(key: &str, v: &[Real], what: &str) -> Result<[Real; N]> {
    <[Real; N]>::try_from(v)
        .map_err(|_| anyhow::anyhow!("{key}: {} components given, {N} expected: {what}", v.len()))
}

/// A named file the config refers to: it must exist and be a file.
pub(crate) fn existing_file(key: &str, what: &str, full: PathBuf) -> Result<PathBuf> {
    if full.is_dir() {
        bail!("{key}: {} is a directory, not {what}", full.display());
    }
    if !full.is_file() {
        bail!("{key}: {what} {} does not exist", full.display());
    }
    Ok(full)
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_grasp::math::Vec3;

    const GOOD: &str = r#"
[object]
shape = "sphere"
radius = 0.0475

[grasp]
space = "planar"
friction = 0.3
alpha = 0.1
contacts = [ { finger = 1, angle_deg = 30.0 }, { finger = 2, angle_deg = -30.0 } ]
"#;

    fn err(text: &str) -> String {
        format!(
            "{:#}",
            Config::parse(text, Path::new("x.toml")).unwrap_err()
        )
    }

    #[test]
    fn defaults_are_filled_in() {
        let c = Config::parse(GOOD, Path::new("x.toml")).unwrap();
        assert_eq!(
            c.object,
            ObjectSpec::Sphere {
                radius: 0.0475,
                segments: [72, 72]
            }
        );
        assert_eq!(c.grasp.model.edges(), 8);
        assert_eq!(c.grasp.contacts.len(), 2);
    }

    #[test]
    fn a_table_reads_as_its_text() {
        let table: toml::Table = toml::from_str(GOOD).unwrap();
        let path = Path::new("x.toml");
        assert_eq!(
            Config::from_table(table.clone(), path).unwrap(),
            Config::parse(GOOD, path).unwrap()
        );
        let mut bad = table;
        bad.insert("bogus".into(), toml::Value::Integer(1));
        let e = format!("{:#}", Config::from_table(bad, path).unwrap_err());
        assert!(e.contains("bogus"), "{e}");
    }

    /// A push of the object is read with its defaults, refused without MuJoCo, without a
    /// force or torque to time, or too hard, each by its key.
    #[test]
    fn a_push_is_read_and_checked() {
        let mujoco = format!("{GOOD}\n[plant]\nkind = \"mujoco\"\n");
        let c = Config::parse(
            &format!("{mujoco}\n[pipeline]\npush_nm = [0.0, 0.0, 0.05]\npush_at_s = 3.0\n"),
            Path::new("x.toml"),
        )
        .unwrap();
        assert_eq!(
            c.pipeline.push,
            Some(Push {
                force: [0.0; 3],
                torque: [0.0, 0.0, 0.05],
                at: 3.0,
                duration: 0.05,
            })
        );
        assert_eq!(
            Config::parse(&mujoco, Path::new("x.toml"))
                .unwrap()
                .pipeline
                .push,
            None
        );
        let e = err(&format!("{GOOD}\n[pipeline]\npush_n = [1.0, 0.0, 0.0]\n"));
        assert!(e.contains("pipeline.push_n") && e.contains("mujoco"), "{e}");
        let e = err(&format!("{mujoco}\n[pipeline]\npush_at_s = 2.0\n"));
        assert!(
            e.contains("pipeline.push_at_s") && e.contains("no push"),
            "{e}"
        );
        let e = err(&format!("{mujoco}\n[pipeline]\npush_n = [0.0, 0.0, 0.0]\n"));
        assert!(e.contains("a push of nothing"), "{e}");
        let e = err(&format!(
            "{mujoco}\n[pipeline]\npush_n = [200.0, 0.0, 0.0]\n"
        ));
        assert!(e.contains("pipeline.push_n (its magnitude)"), "{e}");
        let e = err(&format!(
            "{mujoco}\n[pipeline]\npush_nm = [0.0, 0.0, 1.0]\npush_ms = 0.0\n"
        ));
        assert!(e.contains("pipeline.push_ms"), "{e}");
    }

    #[test]
    fn errors_name_the_key() {
        assert!(err(&GOOD.replace("alpha = 0.1", "alpha = 0.1\nbogus = 1")).contains("bogus"));
        assert!(err(&GOOD.replace("friction = 0.3", "friction = -0.3")).contains("grasp.friction"));
        assert!(
            err(&GOOD.replace("alpha = 0.1", "alpha = 0.1\ncone_edges = 2"))
                .contains("grasp.cone_edges")
        );
        assert!(err(&GOOD.replace("radius = 0.0475", "radius = 0.0")).contains("object.radius"));
        assert!(err(&GOOD.replace("\"planar\"", "\"3d\"")).contains("grasp.space"));
        assert!(
            err(&GOOD.replace("finger = 2", "finger = 1")).contains("grasp.contacts[1].finger")
        );
        assert!(
            err(&GOOD
                .replace(
                    "shape = \"sphere\"",
                    "shape = \"mesh\"\npath = \"nope.stl\""
                )
                .replace("radius = 0.0475", ""))
            .contains("object.path")
        );
        assert!(err(&GOOD.replace("radius", "radios")).contains("radios"));
    }

    /// Out-of-range values of every section, including NaN and inf (TOML has them), are
    /// refused naming the key, the value in short notation and the range.
    #[test]
    fn values_outside_their_bounds_are_refused_by_key_value_and_range() {
        let with = |extra: &str| format!("{GOOD}\n{extra}\n");
        for (text, says) in [
            (
                with("[pipeline]\nrate_hz = 1e11"),
                "pipeline.rate_hz: 1e11 is not in the allowed range [10, 2000] Hz",
            ),
            (
                with("[pipeline]\nrate_hz = 100.0\npose_rate_hz = 101.0"),
                "pipeline.pose_rate_hz: 101 is not in the allowed range [1, 100] Hz",
            ),
            (
                with("[pipeline]\npose_noise_deg = 1e300"),
                "pipeline.pose_noise_deg: 1e300 is not in the allowed range [0, 1] deg",
            ),
            (
                with("[plan]\nstep_deg = 360.0"),
                "plan.step_deg: 360 is not in the allowed range (0, 30] deg",
            ),
            (
                with("[plan]\nrotation_deg = inf"),
                "plan.rotation_deg: inf is not in the allowed range (0, 36000] deg",
            ),
            (
                with("[visualizer]\nqueue = 0"),
                "visualizer.queue: 0 is not in the allowed range 1 to 4096",
            ),
            (
                GOOD.replace("friction = 0.3", "friction = 1e300"),
                "grasp.friction: 1e300 is not in the allowed range [0, 2]",
            ),
            (
                GOOD.replace("radius = 0.0475", "radius = nan"),
                "object.radius: NaN is not in the allowed range [0.001, 1] m",
            ),
            (
                GOOD.replace("radius = 0.0475", "radius = 0.0475\nsegments = [361, 10]"),
                "object.segments[0]: 361 is not in the allowed range 3 to 360",
            ),
        ] {
            let e = err(&text);
            assert!(e.contains(says), "{says}: {e}");
        }
        // Any latency within the range: the estimator is stable at any (nodes/src/estimator.rs).
        let c = Config::parse(
            &with("[pipeline]\npose_latency_ms = 1000.0"),
            Path::new("x.toml"),
        )
        .unwrap();
        assert_eq!(c.pipeline.pose_latency, 1.0);
        // The ends of a range are inside it.
        let c = Config::parse(
            &with("[pipeline]\nrate_hz = 2000.0\npose_rate_hz = 2000.0\npose_latency_ms = 1.5\nmax_input_age_ms = 1e-3"),
            Path::new("x.toml"),
        )
        .unwrap();
        assert_eq!(c.pipeline.pose_rate_hz, 2000.0);
    }

    #[test]
    fn a_recording_s_parts_are_the_file_then_numbered_files_beside_it() {
        let dir = std::env::temp_dir().join(format!("icrflow-rrd-parts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.rrd");
        assert_eq!(rrd_part(&path, 1), path);
        assert_eq!(rrd_part(&path, 3), dir.join("run.3.rrd"));
        assert!(rrd_parts(&path).is_empty());
        for n in [1, 2, 4] {
            std::fs::write(rrd_part(&path, n), b"x").unwrap();
        }
        // Consecutive parts only: a stray part 4 after a gap is not one of them.
        assert_eq!(rrd_parts(&path), [path.clone(), dir.join("run.2.rrd")]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_split_pipeline_names_known_nodes_and_needs_zenoh() {
        let with = |extra: &str| format!("{GOOD}\n{extra}");
        let split = "[pipeline]\nnodes = [\"planner\", \"wrench\"]\n";
        let c = Config::parse(&with(split), Path::new("t.toml")).unwrap();
        // Start order, whatever the order written.
        assert_eq!(c.pipeline.nodes, ["wrench", "planner"]);
        assert!(c.pipeline.split());
        let all = Config::parse(GOOD, Path::new("t.toml")).unwrap();
        assert_eq!(all.pipeline.nodes.len(), 5);
        assert!(!all.pipeline.split());
        for (extra, says) in [
            ("[pipeline]\nnodes = []", "names no node"),
            (
                "[pipeline]\nnodes = [\"plant\", \"mixer\"]",
                "unknown node \"mixer\"",
            ),
            ("[pipeline]\nnodes = [\"plant\", \"plant\"]", "named twice"),
            (
                &format!("{split}[zenoh]\nenabled = false"),
                "zenoh.enabled must be true",
            ),
            (
                "[zenoh]\nlink_users = [\"robot\"]",
                "zenoh.link_users: needs zenoh.users_file",
            ),
        ] {
            let e = err(&with(extra));
            assert!(e.contains(says), "{extra}: {e}");
        }
    }

    /// The same hand written with link lengths in TOML and as a URDF gives the same forward
    /// kinematics (the paper hand, whose URDF is `config/hands/paper_hand.urdf`).
    #[test]
    fn toml_and_urdf_hands_agree() {
        let dir = Path::new(
            &std::env::var_os("CARGO_MANIFEST_DIR")
                .unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into()),
        )
        .join("../config");
        let mut links = String::from("[hand]\nfingertip_radius = 0.025\n");
        let mut urdf = String::from("[hand]\nurdf = \"hands/paper_hand.urdf\"\n");
        for (f, angle) in [(1, 45.0_f64), (2, -45.0), (3, -135.0), (4, 135.0)] {
            let a = angle.to_radians();
            links.push_str(&format!(
                "[[hand.fingers]]\nfinger = {f}\nbase = [{}, {}]\nbase_yaw_deg = {}\nlinks = [0.06, 0.045, 0.025]\nlimits_deg = [[-90.0, 90.0], [-120.0, 120.0], [-120.0, 120.0]]\n",
                0.15 * a.cos(),
                0.15 * a.sin(),
                angle + 180.0
            ));
            urdf.push_str(&format!(
                "[[hand.fingers]]\nfinger = {f}\ntip_link = \"f{f}_tip\"\n"
            ));
        }
        let build = |hand: &str| {
            Config::parse(&format!("{GOOD}{hand}"), &dir.join("x.toml"))
                .unwrap()
                .hand
                .build()
                .unwrap()
        };
        let (a, b) = (build(&links), build(&urdf));
        assert_eq!(a.fingers.len(), 4);
        for (fa, fb) in a.fingers.iter().zip(&b.fingers) {
            assert_eq!(fa.tip_radius, fb.tip_radius);
            for k in 0..50 {
                let q: Vec<Real> = (0..3)
                    .map(|j| {
                        let t = ((k * 3 + j) as Real * 0.618_034).fract();
                        let joint = &fa.joints[j];
                        joint.lower + t * (joint.upper - joint.lower)
                    })
                    .collect();
                let (pa, pb) = (fa.fk(&q), fb.fk(&q));
                assert!((pa.tip_centre - pb.tip_centre).norm() < 1e-12);
                assert!((pa.cap_axis - pb.cap_axis).norm() < 1e-12);
            }
        }
    }

    fn config_dir() -> std::path::PathBuf {
        Path::new(
            &std::env::var_os("CARGO_MANIFEST_DIR")
                .unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into()),
        )
        .join("../config")
    }

    /// A planar hand of link-length fingers (the paper's, written out).
    const LINK_HAND: &str = "[hand]\nfingertip_radius = 0.025\n[[hand.fingers]]\nfinger = 1\nbase = [0.106, 0.106]\nbase_yaw_deg = 225.0\nlinks = [0.06, 0.045, 0.025]\nlimits_deg = [[-90.0, 90.0], [-120.0, 120.0], [-120.0, 120.0]]\n[[hand.fingers]]\nfinger = 2\nbase = [0.106, -0.106]\nbase_yaw_deg = 135.0\nlinks = [0.06, 0.045, 0.025]\nlimits_deg = [[-90.0, 90.0], [-120.0, 120.0], [-120.0, 120.0]]\n";

    /// A spatial hand: the Allegro's, from `config/allegro_sphere.toml`.
    fn allegro() -> String {
        std::fs::read_to_string(config_dir().join("allegro_sphere.toml")).unwrap()
    }

    /// Every vector key takes exactly its components: one more or one fewer is refused
    /// naming the key, the count given and the count expected (TOML's deserializer drops a
    /// 4th component of a 3-array without a word); the right count is read.
    #[test]
    fn a_vector_key_takes_exactly_its_components() {
        let mujoco = format!("{GOOD}\n[plant]\nkind = \"mujoco\"\n");
        let links = format!("{GOOD}{LINK_HAND}");
        let urdf = format!(
            "{GOOD}[hand]\nurdf = \"hands/paper_hand.urdf\"\nurdf_origin = [0.0, 0.0, 0.0]\n[[hand.fingers]]\nfinger = 1\ntip_link = \"f1_tip\"\n[[hand.fingers]]\nfinger = 2\ntip_link = \"f2_tip\"\n"
        );
        let path = config_dir().join("x.toml");
        let parse = |text: &str| Config::parse(text, &path);
        for (text, says) in [
            (
                format!("{GOOD}\n[plan]\naxis = [0.0, 0.0, 1.0, 5.0]\n"),
                "plan.axis: 4 components given, 3 expected: [x, y, z]",
            ),
            (
                format!("{GOOD}\n[plan]\naxis = [0.0, 1.0]\n"),
                "plan.axis: 2 components given, 3 expected",
            ),
            (
                GOOD.replace(
                    "{ finger = 2, angle_deg = -30.0 }",
                    "{ finger = 2, point = [0.041, -0.024, 0.0, 1.0] }",
                ),
                "grasp.contacts[1].point: 4 components given, 3 expected",
            ),
            (
                urdf.replace(
                    "urdf_origin = [0.0, 0.0, 0.0]",
                    "urdf_origin = [0.0, 0.0, 0.0, 1.0]",
                ),
                "hand.urdf_origin: 4 components given, 3 expected",
            ),
            (
                urdf.replace(
                    "urdf_origin = [0.0, 0.0, 0.0]",
                    "urdf_rpy_deg = [0.0, 0.0, 0.0, 90.0]",
                ),
                "hand.urdf_rpy_deg: 4 components given, 3 expected",
            ),
            (
                links.replacen("base = [0.106, 0.106]", "base = [0.106, 0.106, 0.0]", 1),
                "hand.fingers[0].base: 3 components given, 2 expected",
            ),
            (
                links.replacen(
                    "[-120.0, 120.0], [-120.0, 120.0]]",
                    "[-120.0, 120.0, 5.0], [-120.0, 120.0]]",
                    1,
                ),
                "hand.fingers[0].limits_deg[1]: 3 components given, 2 expected",
            ),
            (
                format!("{GOOD}\n[plant]\ngravity = [0.0, 0.0, -9.81, 1.0]\n"),
                "plant.gravity: 4 components given, 3 expected",
            ),
            (
                format!("{mujoco}\n[pipeline]\npush_n = [1.0, 0.0, 0.0, 1.0]\n"),
                "pipeline.push_n: 4 components given, 3 expected",
            ),
            (
                format!("{mujoco}\n[pipeline]\npush_nm = [0.0, 0.05]\n"),
                "pipeline.push_nm: 2 components given, 3 expected",
            ),
        ] {
            let e = format!("{:#}", parse(&text).unwrap_err());
            assert!(e.contains(says), "{says}: {e}");
        }
        // The right counts are read as given.
        let c = parse(&format!(
            "{GOOD}\n[plan]\naxis = [0, 0, 2]\n[plant]\ngravity = [0.0, 0.0, -9.81]\n"
        ))
        .unwrap();
        assert_eq!(c.turn.axis, Vec3::z());
        assert_eq!(c.plant.gravity, [0.0, 0.0, -9.81]);
        let c = parse(&urdf.replace("[0.0, 0.0, 0.0]", "[0.0, 0.0, 0.01]")).unwrap();
        let HandSpec::Urdf { root, .. } = c.hand else {
            panic!("a URDF hand")
        };
        assert_eq!(root.translation.vector, Vec3::new(0.0, 0.0, 0.01));
        let c = parse(&links).unwrap();
        let HandSpec::Links { fingers, .. } = c.hand else {
            panic!("a link-length hand")
        };
        assert_eq!(fingers[0].base[..2], [0.106, 0.106]);
        assert_eq!(
            fingers[0].limits[1],
            [-120.0_f64.to_radians(), 120.0_f64.to_radians()]
        );
    }

    /// Each key that has no effect where it is given is refused by `validate`, naming the key
    /// and the context; the same key where it acts is accepted.
    #[test]
    fn a_key_without_effect_in_its_context_is_refused_naming_it() {
        let mujoco = "[plant]\nkind = \"mujoco\"\n";
        for (key, value) in [
            ("timestep_ms", "1.0"),
            ("kp", "5.0"),
            ("kv", "0.05"),
            ("noslip_iterations", "5"),
            ("squeeze_mm", "1.0"),
            ("feedforward", "false"),
        ] {
            let e = err(&format!("{GOOD}\n[plant]\n{key} = {value}\n"));
            assert!(
                e.contains(&format!("plant.{key}: ")) && e.contains("with the kinematic plant"),
                "{key}: {e}"
            );
            let e = err(&format!(
                "{GOOD}\n[plant]\nkind = \"kinematic\"\n{key} = {value}\n"
            ));
            assert!(e.contains(&format!("plant.{key}: ")), "{key}: {e}");
            Config::parse(
                &format!("{GOOD}\n{mujoco}{key} = {value}\n"),
                Path::new("x.toml"),
            )
            .unwrap();
        }
        // Keys the kinematic plant's run reads (the hand command node's force targets).
        Config::parse(
            &format!("{GOOD}\n[plant]\ngravity = [0.0, 0.0, -9.81]\ndensity = 800.0\nfriction_margin = 0.1\n"),
            Path::new("x.toml"),
        )
        .unwrap();
        let e = err(&format!("{GOOD}\n[pipeline]\nslip_at_s = 2.0\n"));
        assert!(
            e.contains("pipeline.slip_at_s: there is no slip to time"),
            "{e}"
        );
        let e = err(&format!(
            "{GOOD}\n[pipeline]\nslip_deg = 0.0\nslip_at_s = 2.0\n"
        ));
        assert!(e.contains("pipeline.slip_at_s"), "{e}");
        Config::parse(
            &format!("{GOOD}\n[pipeline]\nslip_deg = 5.0\nslip_at_s = 2.0\n"),
            Path::new("x.toml"),
        )
        .unwrap();
        for mode in ["spawn", "connect"] {
            let e = err(&format!(
                "{GOOD}\n[visualizer]\nmode = \"{mode}\"\nrrd = \"x.rrd\"\n"
            ));
            assert!(
                e.contains("visualizer.rrd: ") && e.contains(&format!("mode = \"{mode}\"")),
                "{e}"
            );
        }
        let e = err(&format!("{GOOD}{LINK_HAND}").replace(
            "fingertip_radius = 0.025\n",
            "fingertip_radius = 0.025\nurdf_rpy_deg = [0.0, 0.0, 90.0]\n",
        ));
        assert!(
            e.contains("hand.urdf_rpy_deg: ") && e.contains("link lengths (no hand.urdf)"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            Config::parse(
                &format!("{GOOD}[hand]\nurdf = \"hands/paper_hand.urdf\"\n[[hand.fingers]]\nfinger = 1\ntip_link = \"f1_tip\"\nbase_yaw_deg = 10.0\n"),
                &config_dir().join("x.toml"),
            )
            .unwrap_err()
        );
        assert!(
            e.contains("hand.fingers[0].base_yaw_deg: ") && e.contains("a URDF hand takes"),
            "{e}"
        );
    }

    /// The keys of one planner are refused for the other's hand by `Setup::new`, naming the
    /// key and the hand's kind; `plant.link_radius_mm` for a planar hand on the kinematic
    /// plant likewise.
    #[test]
    fn a_planner_s_key_is_refused_for_the_other_planner_s_hand() {
        let setup = |text: &str| {
            let path = config_dir().join("x.toml");
            crate::Setup::new(&Config::parse(text, &path)?).map(|_| ())
        };
        let planar = |extra: &str| format!("{GOOD}\n{extra}\n");
        for (text, key) in [
            (
                planar("[plan]\nmin_mobility_mm = 10.0"),
                "plan.min_mobility_mm",
            ),
            (
                planar("[plan]\nneighbour_alpha = 0.05")
                    .replace("space = \"planar\"", "space = \"spatial\""),
                "plan.neighbour_alpha",
            ),
            (
                planar("[plant]\nlink_radius_mm = 5.0"),
                "plant.link_radius_mm",
            ),
        ] {
            let e = format!("{:#}", setup(&text).unwrap_err());
            assert!(
                e.contains(&format!("{key}: ")) && e.contains("this hand is planar"),
                "{key}: {e}"
            );
        }
        setup(&planar(
            "[plan]\nmin_manipulability = 1e-3\nattach_resolution_deg = 1.0\naxis = [0, 0, 1]",
        ))
        .unwrap();
        setup(&planar("[plant]\nkind = \"mujoco\"\nlink_radius_mm = 5.0")).unwrap();
        let spatial = allegro();
        for key in ["min_manipulability = 1e-3", "attach_resolution_deg = 1.0"] {
            let text = spatial.replace("[plan]\n", &format!("[plan]\n{key}\n"));
            let e = format!("{:#}", setup(&text).unwrap_err());
            let key = key.split(' ').next().unwrap_or_default();
            assert!(
                e.contains(&format!("plan.{key}: ")) && e.contains("this hand is spatial"),
                "{key}: {e}"
            );
        }
        // (The Allegro config gives plant.link_radius_mm itself.)
        assert!(spatial.contains("[plant]\nlink_radius_mm = 9.8"));
        let text = spatial.replace("[plan]\n", "[plan]\nmin_mobility_mm = 5.0\n");
        setup(&text).unwrap();
    }
}
