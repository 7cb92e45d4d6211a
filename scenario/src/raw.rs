//! The config file as written: serde structs that reject unknown keys.
//!
//! Vector keys are lists (`Vec`), their length checked by validation naming the key
//! (`config::components`): TOML's deserializer fills a fixed-size array from the first
//! components of a longer list and drops the rest without a word.

use std::path::PathBuf;

use serde::Deserialize;

/// A whole config file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawConfig {
    pub object: RawObject,
    pub grasp: RawGrasp,
    pub hand: Option<RawHand>,
    pub plan: Option<RawPlan>,
    pub pipeline: Option<RawPipeline>,
    pub plant: Option<RawPlant>,
    pub zenoh: Option<RawZenoh>,
    pub visualizer: Option<RawVisualizer>,
}

/// `[visualizer]`: the Rerun recording of a run.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawVisualizer {
    pub enabled: Option<bool>,
    pub mode: Option<String>,
    pub rrd: Option<PathBuf>,
    pub url: Option<String>,
    pub rate_hz: Option<f64>,
    pub queue: Option<usize>,
}

/// `[zenoh]`: the bridge between the local bus and Zenoh.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawZenoh {
    pub enabled: Option<bool>,
    pub mode: Option<String>,
    pub listen: Option<Vec<String>>,
    pub connect: Option<Vec<String>>,
    pub scouting: Option<bool>,
    pub read_only: Option<bool>,
    /// `user:password` lines, relative to the config file.
    pub users_file: Option<PathBuf>,
    pub link_users: Option<Vec<String>>,
    pub user: Option<String>,
    pub monitor: Option<Vec<String>>,
}

/// `[plant]`: what the pipeline's plant simulates.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawPlant {
    pub kind: Option<String>,
    pub timestep_ms: Option<f64>,
    pub gravity: Option<Vec<f64>>,
    pub density: Option<f64>,
    pub link_radius_mm: Option<f64>,
    pub kp: Option<f64>,
    pub kv: Option<f64>,
    pub noslip_iterations: Option<usize>,
    pub squeeze_mm: Option<f64>,
    pub feedforward: Option<bool>,
    pub friction_margin: Option<f64>,
}

/// `[pipeline]`: the processes of `icrflow run`.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawPipeline {
    pub rig: Option<String>,
    pub rate_hz: Option<f64>,
    pub joint_speed_deg_s: Option<f64>,
    pub joint_noise_deg: Option<f64>,
    pub pose_rate_hz: Option<f64>,
    pub pose_noise_deg: Option<f64>,
    pub pose_latency_ms: Option<f64>,
    pub max_input_age_ms: Option<f64>,
    pub min_normal_force: Option<f64>,
    pub max_hold_s: Option<f64>,
    pub slip_deg: Option<f64>,
    pub slip_at_s: Option<f64>,
    pub push_n: Option<Vec<f64>>,
    pub push_nm: Option<Vec<f64>>,
    pub push_at_s: Option<f64>,
    pub push_ms: Option<f64>,
    pub seed: Option<u64>,
    pub nodes: Option<Vec<String>>,
    pub realtime_priority: Option<i64>,
    pub max_pose_innovation_deg: Option<f64>,
    pub max_contact_residual_mm: Option<f64>,
    pub hung_restart_s: Option<f64>,
}

/// `[object]`: the shape is chosen by `shape`.
#[derive(Debug, Deserialize)]
#[serde(tag = "shape", rename_all = "lowercase", deny_unknown_fields)]
pub enum RawObject {
    Sphere {
        radius: f64,
        /// `[longitude, latitude]` segments.
        segments: Option<[usize; 2]>,
    },
    Ellipsoid {
        semi_axes: [f64; 3],
        segments: Option<[usize; 2]>,
    },
    Cuboid {
        half_extents: [f64; 3],
        /// Quads along each edge of each face.
        segments: Option<usize>,
    },
    Cylinder {
        radius: f64,
        height: f64,
        /// `[around, along the axis]` segments.
        segments: Option<[usize; 2]>,
    },
    Mesh {
        /// STL or OBJ file, relative to the config file.
        path: PathBuf,
    },
}

/// `[grasp]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawGrasp {
    pub space: String,
    pub friction: f64,
    pub cone_edges: Option<usize>,
    pub alpha: f64,
    pub rho: Option<f64>,
    pub contacts: Vec<RawContact>,
}

/// `[[grasp.contacts]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawContact {
    pub finger: u32,
    pub angle_deg: Option<f64>,
    pub point: Option<Vec<f64>>,
    pub cap_angle_deg: Option<f64>,
}

/// `[hand]`: fingers from link lengths, or from a URDF file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawHand {
    pub urdf: Option<PathBuf>,
    /// URDF root placement in the hand frame: `[x, y, z]` (m).
    pub urdf_origin: Option<Vec<f64>>,
    /// URDF root orientation: `[roll, pitch, yaw]` (deg).
    pub urdf_rpy_deg: Option<Vec<f64>>,
    pub fingertip_radius: Option<f64>,
    pub cap_half_angle_deg: Option<f64>,
    pub fingers: Vec<RawFinger>,
}

/// `[[hand.fingers]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawFinger {
    pub finger: u32,
    /// Link-length fingers: base position `[x, y]` (m) in the hand's plane.
    pub base: Option<Vec<f64>>,
    pub base_yaw_deg: Option<f64>,
    pub links: Option<Vec<f64>>,
    pub limits_deg: Option<Vec<Vec<f64>>>,
    /// URDF fingers: the fingertip link.
    pub tip_link: Option<String>,
    pub home_deg: Option<Vec<f64>>,
    pub fingertip_radius: Option<f64>,
}

/// `[plan]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPlan {
    pub rotation_deg: Option<f64>,
    pub step_deg: Option<f64>,
    pub cap_margin_deg: Option<f64>,
    pub min_manipulability: Option<f64>,
    pub max_steps: Option<usize>,
    pub max_plan_s: Option<f64>,
    pub attach_resolution_deg: Option<f64>,
    pub squeeze_reserve_mm: Option<f64>,
    pub region_erosion: Option<usize>,
    pub neighbour_alpha: Option<f64>,
    pub neighbour_rings: Option<usize>,
    pub alpha: Option<f64>,
    pub axis: Option<Vec<f64>>,
    pub min_mobility_mm: Option<f64>,
}
