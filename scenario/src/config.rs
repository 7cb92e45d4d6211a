//! Configuration: parsed from TOML in two steps, raw serde structs that reject unknown keys
//! ([`raw`]), then this validated, typed config, whose [`Config::load`] is the only way in.
//! Every error names the offending key. The keys are documented in `config/README.md`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::wrench::{ContactModel, Space};

use icrflow_grasp::math::{Isometry3, UnitQuaternion};
use icrflow_plan::hand::{Hand, planar_finger};
use icrflow_plan::planner::Settings;
use icrflow_plan::urdf::UrdfFinger;

use crate::bounds::{self, Count, Range, num};
use crate::raw::{
    self, RawConfig, RawContact, RawHand, RawObject, RawPipeline, RawPlan, RawVisualizer, RawZenoh,
};

/// Default number of friction-cone edges.
pub const DEFAULT_CONE_EDGES: usize = 8;
/// Default sphere/ellipsoid discretisation (the paper's 72 x 72).
pub const DEFAULT_SEGMENTS: [usize; 2] = [72, 72];

/// The node processes of the control loop, in start order: the names `pipeline.nodes` takes.
/// The one definition: the pipeline's topic graph (`icrflow_interfaces::topics`) and `run`
/// name the same nodes.
pub const NODES: [&str; 5] = ["plant", "estimator", "wrench", "planner", "command"];

/// A validated object description.
#[derive(Debug, Clone, PartialEq)]
pub enum ObjectSpec {
    /// UV sphere.
    Sphere {
        /// Radius (m).
        radius: Real,
        /// Longitude, latitude segments.
        segments: [usize; 2],
    },
    /// UV ellipsoid.
    Ellipsoid {
        /// Semi-axes (m).
        semi_axes: [Real; 3],
        /// Longitude, latitude segments.
        segments: [usize; 2],
    },
    /// Box.
    Cuboid {
        /// Half extents (m).
        half_extents: [Real; 3],
        /// Quads per face edge.
        segments: usize,
    },
    /// Cylinder about z.
    Cylinder {
        /// Radius (m).
        radius: Real,
        /// Height (m).
        height: Real,
        /// Segments around and along the axis.
        segments: [usize; 2],
    },
    /// A mesh file (absolute path, checked to exist).
    Mesh {
        /// Path to the STL or OBJ file.
        path: PathBuf,
    },
}

impl ObjectSpec {
    /// Builds (and validates) the object.
    pub fn build(&self) -> Result<Object> {
        self.build_with(&mut icrflow_grasp::progress::Silent)
    }

    /// [`ObjectSpec::build`], reporting a mesh file's loading to `progress`.
    pub fn build_with(
        &self,
        progress: &mut dyn icrflow_grasp::progress::Progress,
    ) -> Result<Object> {
        let object = match self {
            ObjectSpec::Sphere { radius, segments } => {
                Object::sphere(*radius, segments[0], segments[1])
            }
            ObjectSpec::Ellipsoid {
                semi_axes,
                segments,
            } => Object::ellipsoid(Vec3::from(*semi_axes), segments[0], segments[1]),
            ObjectSpec::Cuboid {
                half_extents,
                segments,
            } => Object::cuboid(Vec3::from(*half_extents), *segments),
            ObjectSpec::Cylinder {
                radius,
                height,
                segments,
            } => Object::cylinder(*radius, *height, segments[0], segments[1]),
            ObjectSpec::Mesh { path } => Object::from_file_with(path, progress),
        };
        match self {
            // The mesh error names the file.
            ObjectSpec::Mesh { .. } => object.context("object"),
            _ => object.with_context(|| format!("object: {}", self.describe())),
        }
    }

    /// One-line description.
    pub fn describe(&self) -> String {
        match self {
            ObjectSpec::Sphere { radius, segments } => {
                format!(
                    "sphere r = {radius} m, {} x {} segments",
                    segments[0], segments[1]
                )
            }
            ObjectSpec::Ellipsoid {
                semi_axes,
                segments,
            } => format!(
                "ellipsoid semi-axes {:?} m, {} x {} segments",
                semi_axes, segments[0], segments[1]
            ),
            ObjectSpec::Cuboid {
                half_extents,
                segments,
            } => format!("box half-extents {half_extents:?} m, {segments} quads per edge"),
            ObjectSpec::Cylinder {
                radius,
                height,
                segments,
            } => format!(
                "cylinder r = {radius} m, h = {height} m, {} x {} segments",
                segments[0], segments[1]
            ),
            ObjectSpec::Mesh { path } => format!("mesh {}", path.display()),
        }
    }
}

/// Where a contact is, as given in the config.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactSpec {
    /// Angle (radians) on the object's section in the hand's plane.
    Angle(Real),
    /// Body-frame point (m).
    Point(Vec3),
}

/// One finger's contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FingerContact {
    /// Finger number as in the config.
    pub finger: u32,
    /// Where it touches.
    pub at: ContactSpec,
    /// Where the contact lies on the fingertip cap (rad from the cap axis), if given.
    pub cap_angle: Option<Real>,
}

/// Default fingertip cap half-angle (a hemisphere).
pub const DEFAULT_CAP_HALF_ANGLE_DEG: Real = 90.0;

/// A finger given by link lengths.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkFinger {
    /// Finger number.
    pub finger: u32,
    /// Base position (m) and yaw of the first link at q = 0 (rad).
    pub base: [Real; 3],
    /// Link lengths (m); the last ends at the fingertip centre.
    pub links: Vec<Real>,
    /// Joint limits (rad).
    pub limits: Vec<[Real; 2]>,
    /// Home pose (rad).
    pub home: Option<Vec<Real>>,
    /// Fingertip radius (m).
    pub tip_radius: Real,
}

/// The validated `[hand]` section.
#[derive(Debug, Clone, PartialEq)]
pub enum HandSpec {
    /// No `[hand]`: the paper's four-finger planar hand (`icrflow_plan::paper`).
    Paper,
    /// Fingers from link lengths.
    Links {
        /// Cap half-angle (rad).
        cap_half_angle: Real,
        /// The fingers.
        fingers: Vec<LinkFinger>,
    },
    /// Fingers from a URDF file.
    Urdf {
        /// The file (checked to exist).
        path: PathBuf,
        /// Placement of the URDF's root in the hand frame.
        root: Isometry3,
        /// The fingers.
        fingers: Vec<UrdfFinger>,
    },
}

impl HandSpec {
    /// Builds the hand; errors name the finger.
    pub fn build(&self) -> Result<Hand> {
        let fingers = match self {
            HandSpec::Paper => return Ok(icrflow_plan::paper::hand()),
            HandSpec::Links {
                cap_half_angle,
                fingers,
            } => fingers
                .iter()
                .map(|f| {
                    planar_finger(
                        f.finger,
                        f.base,
                        &f.links,
                        &f.limits,
                        f.tip_radius,
                        *cap_half_angle,
                        f.home.clone(),
                    )
                })
                .collect::<Result<Vec<_>, _>>()
                .context("hand")?,
            HandSpec::Urdf {
                path,
                root,
                fingers: specs,
            } => {
                let fingers =
                    icrflow_plan::urdf::fingers_from_file(path, *root, specs).context("hand")?;
                for (i, (spec, f)) in specs.iter().zip(&fingers).enumerate() {
                    let max = bounds::MESSAGE_JOINTS;
                    if f.dof() > max {
                        bail!(
                            "hand.fingers[{i}]: finger {} (tip link {:?}) has {} joints from the URDF's root, more than the {max} a pipeline message carries per finger (icrflow_interfaces::MAX_JOINTS)",
                            f.id,
                            spec.tip_link,
                            f.dof()
                        );
                    }
                    if spec.tip_radius.is_none() {
                        bounds::FINGERTIP_RADIUS
                            .check(
                                &format!(
                                    "hand.fingers[{i}]: finger {}'s fingertip radius (the sphere of link {:?} in {})",
                                    f.id,
                                    spec.tip_link,
                                    path.display()
                                ),
                                f.tip_radius,
                            )?;
                    }
                }
                fingers
            }
        };
        Hand::new(fingers).context("hand")
    }
}

/// The validated `[grasp]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspSpec {
    /// Wrench space.
    pub space: Space,
    /// Contact model (friction, cone edges).
    pub model: ContactModel,
    /// Quality margin alpha.
    pub alpha: Real,
    /// Torque normalisation length; `None`: the object's largest distance from its COM.
    pub rho: Option<Real>,
    /// Contacts, in config order.
    pub contacts: Vec<FingerContact>,
}

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
    /// Pipeline settings.
    pub pipeline: PipelineSpec,
    /// What the plant simulates.
    pub plant: PlantSpec,
    /// The Zenoh bridge.
    pub zenoh: ZenohSpec,
    /// The Rerun visualizer.
    pub visualizer: VisualizerSpec,
}

/// Where the visualizer's recording goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Recording {
    /// Saved to an `.rrd` file (relative paths: to the directory `run` is started in).
    Rrd(PathBuf),
    /// Streamed to a Rerun viewer the visualizer spawns (`rerun` on the PATH), listening on
    /// 127.0.0.1 at this port.
    Spawn(u16),
    /// Streamed to a running viewer at this URL (`rerun+http://HOST:PORT/proxy`).
    Connect(String),
}

/// The validated `[visualizer]` section: the Rerun recording of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct VisualizerSpec {
    /// Whether `icrflow run` starts the visualizer node.
    pub enabled: bool,
    /// Where the recording goes.
    pub recording: Recording,
    /// Frames per second of the 3D scene and the time series (plan steps are logged each).
    pub rate_hz: Real,
    /// Frames waiting for the recording at most; beyond, frames are dropped and counted.
    pub queue: usize,
    /// The viewer URL (`visualizer.url`): where `connect` connects, and whose port a spawned
    /// viewer listens on.
    pub url: String,
}

impl Recording {
    /// As text (how `run` hands it to the visualizer, `--recording TARGET`): `rrd:PATH`,
    /// `spawn:PORT` or `connect:URL`.
    pub fn to_text(&self) -> String {
        match self {
            Self::Rrd(p) => format!("rrd:{}", p.display()),
            Self::Spawn(port) => format!("spawn:{port}"),
            Self::Connect(url) => format!("connect:{url}"),
        }
    }

    /// Reads it from its text ([`Recording::to_text`]).
    pub fn parse(value: &str) -> Result<Self> {
        if let Some(p) = value.strip_prefix("rrd:") {
            Ok(Self::Rrd(p.into()))
        } else if let Some(url) = value.strip_prefix("connect:") {
            viewer_url(url)?;
            Ok(Self::Connect(url.into()))
        } else if let Some(port) = value.strip_prefix("spawn:") {
            Ok(Self::Spawn(port.parse().with_context(|| {
                format!("recording target {value:?}: the port is not a number")
            })?))
        } else {
            bail!("recording target {value:?}: expected rrd:PATH, spawn:PORT or connect:URL")
        }
    }
}

/// The default recording file of a config: `out/<config file stem>.rrd`.
pub fn default_rrd(config: &Path) -> PathBuf {
    let stem = config
        .file_stem()
        .map_or_else(|| "run".into(), |s| s.to_string_lossy().into_owned());
    PathBuf::from("out").join(format!("{stem}.rrd"))
}

/// Part `n` of a recording saved to `path`: the file itself for `n` = 1, `STEM.N.rrd` beside it
/// after that (where a restarted visualizer writes, under the same recording id).
pub fn rrd_part(path: &Path, n: u32) -> PathBuf {
    if n <= 1 {
        path.to_path_buf()
    } else {
        path.with_extension("").with_extension(format!("{n}.rrd"))
    }
}

/// The parts of a recording saved to `path` that exist, in order ([`rrd_part`]).
pub fn rrd_parts(path: &Path) -> Vec<PathBuf> {
    (1..)
        .map(|n| rrd_part(path, n))
        .take_while(|p| p.is_file())
        .collect()
}

/// The viewer URL `rerun` listens on by default.
pub const DEFAULT_VIEWER_URL: &str = "rerun+http://127.0.0.1:9876/proxy";

fn visualizer_spec(raw: RawVisualizer, path: &Path) -> Result<VisualizerSpec> {
    let mode = raw.mode.unwrap_or_else(|| "rrd".into());
    let url = raw.url.unwrap_or_else(|| DEFAULT_VIEWER_URL.into());
    let (_, port) = viewer_url(&url).context("visualizer.url")?;
    let recording = match mode.as_str() {
        "rrd" => Recording::Rrd(raw.rrd.unwrap_or_else(|| default_rrd(path))),
        "spawn" => Recording::Spawn(port),
        "connect" => Recording::Connect(url.clone()),
        other => bail!("visualizer.mode: one of \"rrd\", \"spawn\", \"connect\", got {other:?}"),
    };
    let rate_hz = bounds::VISUALIZER_RATE.or("visualizer.rate_hz", raw.rate_hz, 30.0)?;
    let queue = bounds::VISUALIZER_QUEUE.check("visualizer.queue", raw.queue.unwrap_or(256))?;
    Ok(VisualizerSpec {
        enabled: raw.enabled.unwrap_or(true),
        recording,
        rate_hz,
        queue,
        url,
    })
}

/// The host and port of a viewer URL `rerun+http://HOST:PORT/proxy` (or `http://`).
pub fn viewer_url(url: &str) -> Result<(String, u16)> {
    let rest = url
        .strip_prefix("rerun+http://")
        .or_else(|| url.strip_prefix("http://"))
        .with_context(|| format!("{url:?}: expected rerun+http://HOST:PORT/proxy"))?;
    let authority = rest.split('/').next().unwrap_or_default();
    let (host, port) = authority
        .rsplit_once(':')
        .with_context(|| format!("{url:?}: no port (rerun+http://HOST:PORT/proxy)"))?;
    let port: u16 = port
        .parse()
        .with_context(|| format!("{url:?}: port {port:?} is not a number"))?;
    if host.is_empty() {
        bail!("{url:?}: no host");
    }
    Ok((
        host.trim_start_matches('[')
            .trim_end_matches(']')
            .to_string(),
        port,
    ))
}

/// The validated `[zenoh]` section: the bridge between the run's local bus and Zenoh.
#[derive(Debug, Clone, PartialEq)]
pub struct ZenohSpec {
    /// Whether `icrflow run` starts the bridge.
    pub enabled: bool,
    /// Zenoh mode: `peer`, `client` or `router`.
    pub mode: String,
    /// Endpoints the bridge listens on (`tcp/HOST:PORT`).
    pub listen: Vec<String>,
    /// Endpoints it connects to.
    pub connect: Vec<String>,
    /// Multicast scouting (finding peers on the network without `connect`).
    pub scouting: bool,
    /// Remote peers may only subscribe to the rig's key expressions (Zenoh access control):
    /// no put, delete, query or queryable of theirs gets through.
    pub read_only: bool,
    /// A file of `user:password` lines: when given, only peers that authenticate with one of
    /// them may connect (Zenoh's user/password authentication).
    pub users_file: Option<PathBuf>,
    /// Users (from `users_file`) whose hosts run the pipeline's other nodes: the only remote
    /// peers allowed to put the loop topics this host takes from Zenoh (read-only sessions).
    /// Empty without a users file: then any peer that connects may.
    pub link_users: Vec<String>,
    /// The user the bridge logs in as where it connects (`connect`), with the password in
    /// [`PASSWORD_ENV`]: a split pipeline's host that connects to one with a users file.
    pub user: Option<String>,
    /// The local topics published for monitoring.
    pub monitor: Vec<String>,
}

/// The local topics the bridge publishes for monitoring unless `zenoh.monitor` says otherwise.
pub const DEFAULT_MONITOR: [&str; 6] = [
    "joint_state",
    "grasp_state",
    "wrench_space",
    "plan_step",
    "hand_command",
    "node_health",
];
/// The environment variable holding the password of `zenoh.user` (and of `icrflow monitor
/// --user`), so that it is in no file and no command line.
pub const PASSWORD_ENV: &str = "ICRFLOW_ZENOH_PASSWORD";
/// Where the bridge listens unless `zenoh.listen` says otherwise: this machine only.
pub const DEFAULT_LISTEN: &str = "tcp/127.0.0.1:7447";

/// `pipeline.realtime_priority` by default: the SCHED_FIFO priority ros2_control's
/// controller manager asks for, in the middle of the range.
pub const DEFAULT_REALTIME_PRIORITY: i64 = 50;

/// The validated `[pipeline]` section: rates, noise and limits of `icrflow run`.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineSpec {
    /// Rig name: the topics are `icrflow/<rig>/<topic>`.
    pub rig: String,
    /// The plant's and the loop's rate (Hz).
    pub rate_hz: Real,
    /// The plant's joint speed limit (rad/s).
    pub joint_speed: Real,
    /// Standard deviation of the joint encoders' noise (rad).
    pub joint_noise: Real,
    /// Rate of the object-pose measurements (Hz).
    pub pose_rate_hz: Real,
    /// Standard deviation of their rotation noise (rad).
    pub pose_noise: Real,
    /// Their latency (s).
    pub pose_latency: Real,
    /// Oldest input the hand command node acts on (s).
    pub max_input_age: Real,
    /// Smallest fingertip normal force commanded (N).
    pub min_normal_force: Real,
    /// Longest hold a scenario run waits through before it gives up (s).
    pub max_hold: Real,
    /// A slip the simulated plant makes once (rad; 0: none): the object turns by this much
    /// under the fingertips, which stay where they are (a knock; a disturbance for the
    /// planner node to recover from). Circular sections only (`run` refuses others).
    pub slip: Real,
    /// When the slip happens, from the plant's start (s).
    pub slip_at: Real,
    /// A push of the object the MuJoCo plant makes once (`None`: none).
    pub push: Option<Push>,
    /// Seed of the simulated noise.
    pub seed: u64,
    /// The nodes this host runs ([`NODES`] by default); the
    /// others run on other hosts, joined over Zenoh.
    pub nodes: Vec<String>,
    /// SCHED_FIFO priority of the nodes on the measurement-to-command path (1 to 99), or 0:
    /// normal scheduling.
    pub realtime_priority: u8,
    /// Largest smoothed pose innovation of the estimate the hand command node tracks on
    /// (rad); beyond, it holds (the estimate is off the pose measurements).
    pub max_pose_innovation: Real,
    /// Largest root-mean-square distance of the fingertips in contact from the object at
    /// the estimated pose the hand command node tracks on (m).
    pub max_contact_residual: Real,
    /// A node that has sent no heartbeat (health report) for this long is killed and
    /// restarted by `run` (s); one silent for a second is reported at once.
    pub hung_restart: Real,
}

/// A push of the object in MuJoCo (`pipeline.push_n`, `push_nm`, `push_at_s`, `push_ms`): a
/// force through its centre of mass and a torque about it, in the world frame (the hand's),
/// held for a while: a knock the loop has to recover from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// The force (N).
    pub force: [Real; 3],
    /// The torque (N m).
    pub torque: [Real; 3],
    /// When it starts: MuJoCo's time, which runs from the hand's first tracking command (s).
    pub at: Real,
    /// How long it lasts (s).
    pub duration: Real,
}

/// The plant of the pipeline (`plant.kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlantKind {
    /// Our own quasi-static model: fingertips roll by the rolling kinematics, nothing slips.
    Kinematic,
    /// MuJoCo: the hand and object as rigid bodies with soft contacts and friction.
    Mujoco,
}

/// The validated `[plant]` section: what `icrflow-plant` simulates and how the hand is driven.
/// Lengths in metres, angles in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantSpec {
    /// Which plant.
    pub kind: PlantKind,
    /// MuJoCo's timestep (s).
    pub timestep: Real,
    /// Gravity in the hand frame (m/s^2).
    pub gravity: [Real; 3],
    /// The object's density (kg/m^3).
    pub density: Real,
    /// Radius of the links' capsules (m).
    pub link_radius: Real,
    /// Joint servos' position gain (N m/rad) and damping (N m s/rad).
    pub kp: Real,
    /// See `kp`.
    pub kv: Real,
    /// Iterations of MuJoCo's no-slip solver after each step (0: none): without it, friction
    /// under a steady tangential load creeps (MuJoCo's soft contacts), and a grasp that leans on
    /// friction drifts out of the hand.
    pub noslip_iterations: u32,
    /// How far past the commanded fingertip position the servos of the finger commanded with
    /// the largest force aim (m); the others' in proportion to their forces.
    pub squeeze: Real,
    /// Whether the fingertip force targets reach the joints as feed-forward torques.
    pub feedforward: bool,
    /// The fraction of mu the hand command's force targets leave unused at every contact.
    pub friction_margin: Real,
}

impl PlantSpec {
    /// The object's weight as a force on it (N, hand frame), for an object of `volume` m^3.
    pub fn weight(&self, volume: Real) -> [Real; 3] {
        let m = self.density * volume;
        self.gravity.map(|g| m * g)
    }
}

/// `pipeline.max_pose_innovation_deg` by default.
pub const DEFAULT_MAX_POSE_INNOVATION_DEG: Real = 3.0;
/// `pipeline.max_contact_residual_mm` by default.
pub const DEFAULT_MAX_CONTACT_RESIDUAL_MM: Real = 1.5;
/// `pipeline.hung_restart_s` by default.
pub const DEFAULT_HUNG_RESTART_S: Real = 10.0;

impl PipelineSpec {
    /// Whether some of the loop's nodes run on another host.
    pub fn split(&self) -> bool {
        self.nodes.len() < NODES.len()
    }
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
            pipeline,
            plant,
            zenoh,
            visualizer,
        })
    }
}

fn segments(s: [usize; 2], around: Count, along: Count) -> Result<[usize; 2]> {
    around.check("object.segments[0]", s[0])?;
    along.check("object.segments[1]", s[1])?;
    Ok(s)
}

/// Each of `values` in `range`, keys `key[0]`, `key[1]`, ...
fn each<const N: usize>(key: &str, values: [Real; N], range: Range) -> Result<[Real; N]> {
    for (i, x) in values.iter().enumerate() {
        range.check(&format!("{key}[{i}]"), *x)?;
    }
    Ok(values)
}

/// A named file the config refers to: it must exist and be a file.
fn existing_file(key: &str, what: &str, full: PathBuf) -> Result<PathBuf> {
    if full.is_dir() {
        bail!("{key}: {} is a directory, not {what}", full.display());
    }
    if !full.is_file() {
        bail!("{key}: {what} {} does not exist", full.display());
    }
    Ok(full)
}

fn object_spec(raw: RawObject, base: &Path) -> Result<ObjectSpec> {
    Ok(match raw {
        RawObject::Sphere {
            radius,
            segments: s,
        } => ObjectSpec::Sphere {
            radius: bounds::SIZE.check("object.radius", radius)?,
            segments: segments(
                s.unwrap_or(DEFAULT_SEGMENTS),
                bounds::LONGITUDE,
                bounds::LATITUDE,
            )?,
        },
        RawObject::Ellipsoid {
            semi_axes,
            segments: s,
        } => ObjectSpec::Ellipsoid {
            semi_axes: each("object.semi_axes", semi_axes, bounds::SIZE)?,
            segments: segments(
                s.unwrap_or(DEFAULT_SEGMENTS),
                bounds::LONGITUDE,
                bounds::LATITUDE,
            )?,
        },
        RawObject::Cuboid {
            half_extents,
            segments: s,
        } => ObjectSpec::Cuboid {
            half_extents: each("object.half_extents", half_extents, bounds::SIZE)?,
            segments: bounds::CUBOID_SEGMENTS.check("object.segments", s.unwrap_or(8))?,
        },
        RawObject::Cylinder {
            radius,
            height,
            segments: s,
        } => ObjectSpec::Cylinder {
            radius: bounds::SIZE.check("object.radius", radius)?,
            height: bounds::SIZE.check("object.height", height)?,
            segments: segments(
                s.unwrap_or([72, 8]),
                bounds::CYLINDER_AROUND,
                bounds::CYLINDER_ALONG,
            )?,
        },
        RawObject::Mesh { path } => ObjectSpec::Mesh {
            path: existing_file("object.path", "a mesh file", base.join(&path))?,
        },
    })
}

fn grasp_spec(raw: raw::RawGrasp) -> Result<GraspSpec> {
    let space = match raw.space.as_str() {
        "planar" => Space::Planar,
        "spatial" => Space::Spatial,
        other => bail!("grasp.space: must be \"planar\" or \"spatial\", got {other:?}"),
    };
    let edges = raw.cone_edges.unwrap_or(DEFAULT_CONE_EDGES);
    bounds::FRICTION.check("grasp.friction", raw.friction)?;
    let model = ContactModel::new(raw.friction, edges).map_err(|e| {
        let key = match e {
            icrflow_grasp::wrench::WrenchError::ConeEdges { .. } => "grasp.cone_edges",
            _ => "grasp.friction",
        };
        anyhow::anyhow!("{key}: {e}")
    })?;
    let alpha = bounds::ALPHA.check("grasp.alpha", raw.alpha)?;
    let rho = raw
        .rho
        .map(|r| bounds::RHO.check("grasp.rho", r))
        .transpose()?;
    if raw.contacts.is_empty() {
        bail!("grasp.contacts: at least one contact is needed");
    }
    let mut contacts: Vec<FingerContact> = Vec::with_capacity(raw.contacts.len());
    for (i, c) in raw.contacts.into_iter().enumerate() {
        let contact = contact_spec(i, c)?;
        if contacts.iter().any(|o| o.finger == contact.finger) {
            bail!(
                "grasp.contacts[{i}].finger: finger {} appears twice",
                contact.finger
            );
        }
        contacts.push(contact);
    }
    Ok(GraspSpec {
        space,
        model,
        alpha,
        rho,
        contacts,
    })
}

fn contact_spec(i: usize, c: RawContact) -> Result<FingerContact> {
    let at = match (c.angle_deg, c.point) {
        (Some(_), Some(_)) => bail!("grasp.contacts[{i}]: give `angle_deg` or `point`, not both"),
        (None, None) => bail!("grasp.contacts[{i}]: give `angle_deg` or `point`"),
        (Some(a), None) => ContactSpec::Angle(
            bounds::CONTACT_ANGLE
                .check(&format!("grasp.contacts[{i}].angle_deg"), a)?
                .to_radians(),
        ),
        (None, Some(p)) => ContactSpec::Point(Vec3::from(each(
            &format!("grasp.contacts[{i}].point"),
            p,
            bounds::CONTACT_POINT,
        )?)),
    };
    let cap_angle = c
        .cap_angle_deg
        .map(|a| {
            bounds::CAP_ANGLE
                .check(&format!("grasp.contacts[{i}].cap_angle_deg"), a)
                .map(Real::to_radians)
        })
        .transpose()?;
    Ok(FingerContact {
        finger: c.finger,
        at,
        cap_angle,
    })
}

/// An angle of the hand's description (degrees in the file), in radians.
fn degrees(key: &str, x: Real) -> Result<Real> {
    Ok(bounds::HAND_ANGLE.check(key, x)?.to_radians())
}

fn hand_spec(raw: RawHand, base: &Path) -> Result<HandSpec> {
    let cap_half_angle = bounds::CAP_HALF_ANGLE
        .or(
            "hand.cap_half_angle_deg",
            raw.cap_half_angle_deg,
            DEFAULT_CAP_HALF_ANGLE_DEG,
        )?
        .to_radians();
    let radius = raw
        .fingertip_radius
        .map(|r| bounds::FINGERTIP_RADIUS.check("hand.fingertip_radius", r))
        .transpose()?;
    if raw.fingers.is_empty() {
        bail!("hand.fingers: at least one finger is needed");
    }
    bounds::FINGERS.check("hand.fingers (their number)", raw.fingers.len())?;
    let home = |i: usize, h: &Option<Vec<Real>>| -> Result<Option<Vec<Real>>> {
        h.as_ref()
            .map(|v| {
                bounds::JOINTS
                    .check(&format!("hand.fingers[{i}].home_deg (its length)"), v.len())?;
                v.iter()
                    .enumerate()
                    .map(|(j, a)| degrees(&format!("hand.fingers[{i}].home_deg[{j}]"), *a))
                    .collect()
            })
            .transpose()
    };
    let mut seen = Vec::new();
    for (i, f) in raw.fingers.iter().enumerate() {
        if seen.contains(&f.finger) {
            bail!(
                "hand.fingers[{i}].finger: finger {} appears twice",
                f.finger
            );
        }
        seen.push(f.finger);
    }
    match raw.urdf {
        Some(file) => {
            let full = existing_file("hand.urdf", "a URDF file", base.join(&file))?;
            let o = each(
                "hand.urdf_origin",
                raw.urdf_origin.unwrap_or([0.0; 3]),
                bounds::HAND_POSITION,
            )?;
            let r = each(
                "hand.urdf_rpy_deg",
                raw.urdf_rpy_deg.unwrap_or([0.0; 3]),
                bounds::HAND_ANGLE,
            )?
            .map(Real::to_radians);
            let root = Isometry3::from_parts(
                nalgebra::Translation3::new(o[0], o[1], o[2]),
                UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
            );
            let mut fingers = Vec::new();
            for (i, f) in raw.fingers.into_iter().enumerate() {
                let key = |k: &str| format!("hand.fingers[{i}].{k}");
                if f.base.is_some() || f.links.is_some() || f.limits_deg.is_some() {
                    bail!(
                        "{}: a URDF hand takes `tip_link` (and optionally `home_deg`, `fingertip_radius`), not base/links/limits",
                        key("tip_link")
                    );
                }
                let Some(tip_link) = f.tip_link.clone() else {
                    bail!("{}: required for a URDF hand", key("tip_link"));
                };
                let tip_radius = f
                    .fingertip_radius
                    .map(|r| bounds::FINGERTIP_RADIUS.check(&key("fingertip_radius"), r))
                    .transpose()?
                    .or(radius);
                fingers.push(UrdfFinger {
                    id: f.finger,
                    tip_link,
                    tip_radius,
                    cap_half_angle,
                    home: home(i, &f.home_deg)?,
                });
            }
            Ok(HandSpec::Urdf {
                path: full,
                root,
                fingers,
            })
        }
        None => {
            let mut fingers = Vec::new();
            for (i, f) in raw.fingers.into_iter().enumerate() {
                let key = |k: &str| format!("hand.fingers[{i}].{k}");
                if f.tip_link.is_some() {
                    bail!("{}: only for URDF hands (set hand.urdf)", key("tip_link"));
                }
                let Some(b) = f.base else {
                    bail!("{}: required ([x, y] in metres)", key("base"));
                };
                let b = each(&key("base"), b, bounds::HAND_POSITION)?;
                let yaw = degrees(&key("base_yaw_deg"), f.base_yaw_deg.unwrap_or(0.0))?;
                let Some(links) = f.links else {
                    bail!("{}: required (link lengths in metres)", key("links"));
                };
                bounds::JOINTS.check(&format!("{} (their number)", key("links")), links.len())?;
                for (j, l) in links.iter().enumerate() {
                    bounds::LINK.check(&format!("hand.fingers[{i}].links[{j}]"), *l)?;
                }
                let Some(limits) = f.limits_deg else {
                    bail!("{}: required ([lower, upper] per joint)", key("limits_deg"));
                };
                if limits.len() != links.len() {
                    bail!(
                        "{}: {} joint limits for {} links (one joint per link)",
                        key("limits_deg"),
                        limits.len(),
                        links.len()
                    );
                }
                let mut lim = Vec::with_capacity(limits.len());
                for (j, &[lo, hi]) in limits.iter().enumerate() {
                    let k = format!("hand.fingers[{i}].limits_deg[{j}]");
                    let (lo_rad, hi_rad) = (degrees(&k, lo)?, degrees(&k, hi)?);
                    if lo > hi {
                        bail!(
                            "{k}: lower limit {} deg is above the upper limit {} deg (finger {})",
                            num(lo),
                            num(hi),
                            f.finger
                        );
                    }
                    lim.push([lo_rad, hi_rad]);
                }
                let tip_radius = match f
                    .fingertip_radius
                    .map(|r| bounds::FINGERTIP_RADIUS.check(&key("fingertip_radius"), r))
                    .transpose()?
                    .or(radius)
                {
                    Some(r) => r,
                    None => bail!(
                        "hand.fingertip_radius: required (or per finger: {})",
                        key("fingertip_radius")
                    ),
                };
                fingers.push(LinkFinger {
                    finger: f.finger,
                    base: [b[0], b[1], yaw],
                    links,
                    limits: lim,
                    home: home(i, &f.home_deg)?,
                    tip_radius,
                });
            }
            Ok(HandSpec::Links {
                cap_half_angle,
                fingers,
            })
        }
    }
}

fn zenoh_spec(raw: RawZenoh, base: &Path) -> Result<ZenohSpec> {
    let mut names = Vec::new();
    let users_file = match raw.users_file {
        None => None,
        Some(file) => {
            let full = existing_file("zenoh.users_file", "a users file", base.join(&file))?;
            let text = std::fs::read_to_string(&full)
                .with_context(|| format!("zenoh.users_file: cannot read {}", full.display()))?;
            let mut users = 0;
            for (i, line) in text.lines().enumerate() {
                // Zenoh's format: one `user:password` per line, blank lines skipped, no
                // comments.
                let line = line.trim();
                if line.is_empty() {
                    continue;
                }
                match line.split_once(':') {
                    Some((u, p)) if !u.trim().is_empty() && !p.trim().is_empty() => {
                        users += 1;
                        names.push(u.trim().to_string());
                    }
                    _ => bail!(
                        "zenoh.users_file: {} line {}: expected user:password",
                        full.display(),
                        i + 1
                    ),
                }
            }
            if users == 0 {
                bail!("zenoh.users_file: {} names no user", full.display());
            }
            Some(full)
        }
    };
    let mode = raw.mode.unwrap_or_else(|| "peer".into());
    if !matches!(mode.as_str(), "peer" | "client" | "router") {
        bail!("zenoh.mode: one of \"peer\", \"client\", \"router\", got {mode:?}");
    }
    let endpoints = |key: &str, list: Vec<String>| -> Result<Vec<String>> {
        for e in &list {
            check_endpoint(key, e)?;
        }
        Ok(list)
    };
    let monitor = raw
        .monitor
        .unwrap_or_else(|| DEFAULT_MONITOR.iter().map(|t| t.to_string()).collect());
    for t in &monitor {
        if !DEFAULT_MONITOR.contains(&t.as_str()) {
            bail!("zenoh.monitor: unknown topic {t:?}; the topics are {DEFAULT_MONITOR:?}");
        }
    }
    let link_users = raw.link_users.unwrap_or_default();
    for u in &link_users {
        if users_file.is_none() {
            bail!("zenoh.link_users: needs zenoh.users_file (the users peers log in as)");
        }
        if !names.contains(u) {
            bail!("zenoh.link_users: {u:?} is not a user of zenoh.users_file");
        }
    }
    if let Some(u) = &raw.user
        && (u.is_empty() || u.contains(':'))
    {
        bail!("zenoh.user: a user name without ':', got {u:?}");
    }
    Ok(ZenohSpec {
        link_users,
        user: raw.user,
        enabled: raw.enabled.unwrap_or(true),
        mode,
        listen: endpoints(
            "zenoh.listen",
            raw.listen.unwrap_or_else(|| vec![DEFAULT_LISTEN.into()]),
        )?,
        connect: endpoints("zenoh.connect", raw.connect.unwrap_or_default())?,
        scouting: raw.scouting.unwrap_or(false),
        read_only: raw.read_only.unwrap_or(true),
        users_file,
        monitor,
    })
}

/// When a push begins unless `pipeline.push_at_s` says (s of MuJoCo's time).
pub const DEFAULT_PUSH_AT_S: Real = 5.0;
/// How long a push lasts unless `pipeline.push_ms` says (ms).
pub const DEFAULT_PUSH_MS: Real = 50.0;

/// `pipeline.push_*`: a push when a force or a torque is given.
fn push_spec(raw: &RawPipeline) -> Result<Option<Push>> {
    let (at, ms) = (raw.push_at_s, raw.push_ms);
    if raw.push_n.is_none() && raw.push_nm.is_none() {
        if at.is_some() || ms.is_some() {
            bail!(
                "pipeline.push_at_s / push_ms: there is no push to time; give its force (push_n) or torque (push_nm)"
            );
        }
        return Ok(None);
    }
    let vector = |key: &str, v: Option<[f64; 3]>, range: &bounds::Range| -> Result<[Real; 3]> {
        let v = v.unwrap_or([0.0; 3]);
        if v.iter().any(|x| !x.is_finite()) {
            bail!("{key}: every component must be a finite number, got {v:?}");
        }
        range.check(
            &format!("{key} (its magnitude)"),
            v.iter().map(|x| x * x).sum::<f64>().sqrt(),
        )?;
        Ok(v)
    };
    let force = vector("pipeline.push_n", raw.push_n, &bounds::PUSH_FORCE)?;
    let torque = vector("pipeline.push_nm", raw.push_nm, &bounds::PUSH_TORQUE)?;
    if force.iter().chain(&torque).all(|&x| x == 0.0) {
        bail!("pipeline.push_n / push_nm: both are zero, a push of nothing (leave them out)");
    }
    Ok(Some(Push {
        force,
        torque,
        at: bounds::PUSH_AT.or("pipeline.push_at_s", at, DEFAULT_PUSH_AT_S)?,
        duration: bounds::PUSH_DURATION.or("pipeline.push_ms", ms, DEFAULT_PUSH_MS)? * 1e-3,
    }))
}

fn pipeline_spec(raw: RawPipeline) -> Result<PipelineSpec> {
    let push = push_spec(&raw)?;
    let rig = raw.rig.unwrap_or_else(|| "sim".into());
    if rig.is_empty()
        || rig.len() > 48
        || !rig
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
    {
        bail!("pipeline.rig: use 1 to 48 letters, digits, '_' or '-', got {rig:?}");
    }
    let rate_hz = bounds::RATE.or("pipeline.rate_hz", raw.rate_hz, 1000.0)?;
    let pose_rate_hz = bounds::POSE_RATE
        .up_to(
            rate_hz.min(bounds::POSE_RATE.hi),
            "at least one correction a second; at most one per tick of pipeline.rate_hz",
        )
        .or("pipeline.pose_rate_hz", raw.pose_rate_hz, 30.0)?;
    let pose_latency_ms =
        bounds::POSE_LATENCY.or("pipeline.pose_latency_ms", raw.pose_latency_ms, 30.0)?;
    let spec = PipelineSpec {
        rig,
        rate_hz,
        joint_speed: bounds::JOINT_SPEED
            .or("pipeline.joint_speed_deg_s", raw.joint_speed_deg_s, 360.0)?
            .to_radians(),
        joint_noise: bounds::JOINT_NOISE
            .or("pipeline.joint_noise_deg", raw.joint_noise_deg, 0.02)?
            .to_radians(),
        pose_rate_hz,
        pose_noise: bounds::POSE_NOISE
            .or("pipeline.pose_noise_deg", raw.pose_noise_deg, 0.2)?
            .to_radians(),
        pose_latency: pose_latency_ms * 1e-3,
        max_input_age: bounds::INPUT_AGE.or(
            "pipeline.max_input_age_ms",
            raw.max_input_age_ms,
            200.0,
        )? * 1e-3,
        min_normal_force: bounds::NORMAL_FORCE.or(
            "pipeline.min_normal_force",
            raw.min_normal_force,
            1.0,
        )?,
        max_hold: bounds::MAX_HOLD.or("pipeline.max_hold_s", raw.max_hold_s, 30.0)?,
        slip: bounds::SLIP
            .or("pipeline.slip_deg", raw.slip_deg, 0.0)?
            .to_radians(),
        slip_at: bounds::SLIP_AT.or("pipeline.slip_at_s", raw.slip_at_s, 5.0)?,
        push,
        seed: raw.seed.unwrap_or(1),
        nodes: nodes_spec(raw.nodes)?,
        max_pose_innovation: bounds::POSE_INNOVATION
            .or(
                "pipeline.max_pose_innovation_deg",
                raw.max_pose_innovation_deg,
                DEFAULT_MAX_POSE_INNOVATION_DEG,
            )?
            .to_radians(),
        max_contact_residual: bounds::CONTACT_RESIDUAL.or(
            "pipeline.max_contact_residual_mm",
            raw.max_contact_residual_mm,
            DEFAULT_MAX_CONTACT_RESIDUAL_MM,
        )? * 1e-3,
        hung_restart: bounds::HUNG_RESTART.or(
            "pipeline.hung_restart_s",
            raw.hung_restart_s,
            DEFAULT_HUNG_RESTART_S,
        )?,
        realtime_priority: match raw.realtime_priority.unwrap_or(DEFAULT_REALTIME_PRIORITY) {
            p @ 0..=99 => p as u8,
            p => bail!(
                "pipeline.realtime_priority: 0 (normal scheduling) or a SCHED_FIFO priority from 1 to 99, got {p}"
            ),
        },
    };
    // The estimate's own noise must leave the innovation's bound for real errors: the
    // smoothed innovation's noise is a third of the pose noise, the estimate's 0.42 of it.
    if spec.pose_noise > 0.5 * spec.max_pose_innovation {
        bail!(
            "pipeline.pose_noise_deg: at most half of pipeline.max_pose_innovation_deg ({} deg), or the measurements' own noise would hold the hand; got {}",
            num(spec.max_pose_innovation.to_degrees()),
            num(spec.pose_noise.to_degrees())
        );
    }
    Ok(spec)
}

fn plant_spec(raw: crate::raw::RawPlant) -> Result<PlantSpec> {
    let kind = match raw.kind.as_deref() {
        None | Some("kinematic") => PlantKind::Kinematic,
        Some("mujoco") => PlantKind::Mujoco,
        Some(other) => bail!(
            "plant.kind: unknown plant {other:?}; the plants are \"kinematic\" (the default: our quasi-static model) and \"mujoco\""
        ),
    };
    let gravity = raw.gravity.unwrap_or([0.0; 3]);
    for (i, g) in gravity.iter().enumerate() {
        bounds::GRAVITY.check(&format!("plant.gravity[{i}]"), *g)?;
    }
    if gravity[0] != 0.0 || gravity[1] != 0.0 {
        bail!(
            "plant.gravity: only along the hand's z axis (the axis the object turns about), got [{}, {}, {}]: the force targets are solved once per contact set in the object's frame, which a sideways load would turn with the object",
            num(gravity[0]),
            num(gravity[1]),
            num(gravity[2])
        );
    }
    Ok(PlantSpec {
        kind,
        timestep: bounds::TIMESTEP.or("plant.timestep_ms", raw.timestep_ms, 0.5)? * 1e-3,
        gravity,
        density: bounds::DENSITY.or("plant.density", raw.density, 500.0)?,
        link_radius: bounds::LINK_RADIUS.or("plant.link_radius_mm", raw.link_radius_mm, 4.0)?
            * 1e-3,
        kp: bounds::KP.or("plant.kp", raw.kp, 5.0)?,
        kv: bounds::KV.or("plant.kv", raw.kv, 0.05)?,
        noslip_iterations: bounds::NOSLIP.check(
            "plant.noslip_iterations",
            raw.noslip_iterations.unwrap_or(0),
        )? as u32,
        squeeze: bounds::SQUEEZE.or("plant.squeeze_mm", raw.squeeze_mm, 1.0)? * 1e-3,
        feedforward: raw.feedforward.unwrap_or(true),
        friction_margin: bounds::FRICTION_MARGIN.or(
            "plant.friction_margin",
            raw.friction_margin,
            match kind {
                PlantKind::Kinematic => 0.0,
                PlantKind::Mujoco => 0.2,
            },
        )?,
    })
}

fn nodes_spec(raw: Option<Vec<String>>) -> Result<Vec<String>> {
    let Some(nodes) = raw else {
        return Ok(NODES.iter().map(|n| n.to_string()).collect());
    };
    if nodes.is_empty() {
        bail!("pipeline.nodes: names no node; the nodes are {NODES:?}");
    }
    for (i, n) in nodes.iter().enumerate() {
        if !NODES.contains(&n.as_str()) {
            bail!("pipeline.nodes: unknown node {n:?}; the nodes are {NODES:?}");
        }
        if nodes[..i].contains(n) {
            bail!("pipeline.nodes: {n:?} is named twice");
        }
    }
    // Start order, whatever the order written.
    Ok(NODES
        .iter()
        .filter(|n| nodes.iter().any(|m| m == *n))
        .map(|n| n.to_string())
        .collect())
}

/// Planner defaults.
pub const DEFAULT_ROTATION_DEG: Real = 360.0;
/// Default squeeze reserve every contact pose of a plan keeps (mm).
pub const DEFAULT_SQUEEZE_RESERVE_MM: Real = 2.0;
/// Default object rotation per rolling step (deg).
pub const DEFAULT_STEP_DEG: Real = 5.0;

/// What the object turns about, and the spatial planner's own limits (`[plan]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Turn {
    /// The unit axis (hand frame) the object turns about, positive by the right-hand rule
    /// (`plan.axis`, normalised; `[0, 0, 1]` by default, the only axis of a planar hand).
    pub axis: Vec3,
    /// Smallest singular value of a spatial finger's fingertip-centre Jacobian in contact
    /// (m per rad; `plan.min_mobility_mm`).
    pub min_mobility: Real,
}

/// Default `plan.min_mobility_mm`.
pub const DEFAULT_MIN_MOBILITY_MM: Real = 5.0;

fn turn_spec(raw: Option<&RawPlan>) -> Result<Turn> {
    let axis = match raw.and_then(|r| r.axis) {
        None => Vec3::z(),
        Some(a) => {
            let v = Vec3::from(a);
            if !v.iter().all(|x| x.is_finite()) || v.norm() < 1e-9 {
                bail!(
                    "plan.axis: [{}, {}, {}] is not a direction (finite, not zero)",
                    num(a[0]),
                    num(a[1]),
                    num(a[2])
                );
            }
            v.normalize()
        }
    };
    let min_mobility = bounds::MOBILITY.or(
        "plan.min_mobility_mm",
        raw.and_then(|r| r.min_mobility_mm),
        DEFAULT_MIN_MOBILITY_MM,
    )? * 1e-3;
    Ok(Turn { axis, min_mobility })
}

fn plan_spec(raw: Option<RawPlan>, alpha: Real) -> Result<Settings> {
    let raw = raw.unwrap_or(RawPlan {
        rotation_deg: None,
        step_deg: None,
        cap_margin_deg: None,
        min_manipulability: None,
        max_steps: None,
        attach_resolution_deg: None,
        squeeze_reserve_mm: None,
        region_erosion: None,
        neighbour_alpha: None,
        neighbour_rings: None,
        alpha: None,
        axis: None,
        min_mobility_mm: None,
    });
    let rotation =
        bounds::ROTATION.or("plan.rotation_deg", raw.rotation_deg, DEFAULT_ROTATION_DEG)?;
    let step = bounds::STEP.or("plan.step_deg", raw.step_deg, DEFAULT_STEP_DEG)?;
    let cap_margin = bounds::CAP_MARGIN.or("plan.cap_margin_deg", raw.cap_margin_deg, 5.0)?;
    let m = bounds::MANIPULABILITY.or("plan.min_manipulability", raw.min_manipulability, 1e-4)?;
    let max_steps = bounds::MAX_STEPS.check("plan.max_steps", raw.max_steps.unwrap_or(100_000))?;
    // The rolling steps alone: a plan that cannot reach its goal within max_steps is refused
    // before it starts (switches add two steps each on top).
    let rolling = (rotation / step).ceil();
    if rolling >= max_steps as Real {
        bail!(
            "plan.max_steps: {max_steps} steps cannot turn plan.rotation_deg = {} deg in steps of plan.step_deg = {} deg, which takes {} rolling steps (and the start, and two per finger switch)",
            num(rotation),
            num(step),
            num(rolling)
        );
    }
    // The plan's margin: the hand's (`grasp.alpha`, which the command node's gate holds the
    // estimated grasp to), or more, as headroom for contacts the estimate snaps a candidate
    // off the plan's.
    let plan_alpha = bounds::ALPHA.or("plan.alpha", raw.alpha, alpha)?;
    if raw.neighbour_rings.is_some() && raw.neighbour_alpha.is_none() {
        bail!(
            "plan.neighbour_rings: the rings plan.neighbour_alpha is checked over, given without it (nothing is checked)"
        );
    }
    if plan_alpha < alpha {
        bail!(
            "plan.alpha: {} is below grasp.alpha = {}: the plan keeps at least the margin the hand's gate holds to (leave plan.alpha out to plan at grasp.alpha)",
            num(plan_alpha),
            num(alpha)
        );
    }
    Ok(Settings {
        alpha: plan_alpha,
        gate_alpha: alpha,
        goal: rotation.to_radians(),
        step: step.to_radians(),
        cap_margin: cap_margin.to_radians(),
        min_manipulability: m,
        max_steps,
        attach_resolution: bounds::ATTACH_RESOLUTION
            .or("plan.attach_resolution_deg", raw.attach_resolution_deg, 2.0)?
            .to_radians(),
        squeeze_reserve: bounds::SQUEEZE_RESERVE.or(
            "plan.squeeze_reserve_mm",
            raw.squeeze_reserve_mm,
            DEFAULT_SQUEEZE_RESERVE_MM,
        )? * 1e-3,
        region_erosion: bounds::REGION_EROSION
            .check("plan.region_erosion", raw.region_erosion.unwrap_or(0))?,
        neighbour_alpha: raw
            .neighbour_alpha
            .map(|a| bounds::ALPHA.check("plan.neighbour_alpha", a))
            .transpose()?,
        neighbour_rings: bounds::NEIGHBOUR_RINGS
            .check("plan.neighbour_rings", raw.neighbour_rings.unwrap_or(1))?,
    })
}

/// Checks a Zenoh endpoint given under `key` (a config key, or a flag such as `--connect`):
/// `tcp/HOST:PORT` (TCP is the only transport built in), so that a typo is named in our words
/// rather than in Zenoh's.
pub fn check_endpoint(key: &str, e: &str) -> Result<()> {
    let Some((proto, address)) = e.split_once('/') else {
        bail!("{key}: {e:?} is not an endpoint like \"tcp/127.0.0.1:7447\"");
    };
    if proto != "tcp" {
        bail!("{key}: {e:?}: only tcp endpoints are built in, got {proto:?}");
    }
    let address = address.split('#').next().unwrap_or(address);
    let ok = address
        .rsplit_once(':')
        .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok());
    if !ok {
        bail!("{key}: {e:?}: expected tcp/HOST:PORT");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
