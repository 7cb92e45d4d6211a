//! The recording: a thread of its own owns the Rerun stream and logs the frames the node
//! sends it, so that a lagging viewer (Rerun's SDK blocks when its bounded queues are full)
//! only ever blocks this thread; the node drops and counts the frames that find the queue full.

use std::time::Duration;

use anyhow::{Context as _, Result, anyhow};
use icrflow_scenario::Recording;
use rerun::blueprint::{Blueprint, Horizontal, Spatial3DView, TimeSeriesView, Vertical};

use crate::geometry::{Mesh, P3};

/// The entity paths of the recording (documented in the crate's README).
pub mod paths {
    /// The 3D scene, in the hand frame.
    pub const SCENE: &str = "/scene";
    /// The object's pose (its children are in its body frame).
    pub const OBJECT: &str = "/scene/object";
    /// The object's surface.
    pub const OBJECT_MESH: &str = "/scene/object/mesh";
    /// Each finger's ICR (`/scene/object/icr/finger_<n>`), of the current plan step.
    pub const ICR: &str = "/scene/object/icr";
    /// The ICR a free finger attaches into during a switch (the rendezvous region), in each
    /// attach step; cleared otherwise.
    pub const RENDEZVOUS: &str = "/scene/object/rendezvous";
    /// The estimated contact points.
    pub const CONTACTS: &str = "/scene/contacts";
    /// The friction-cone edges at the contacts.
    pub const CONES: &str = "/scene/cones";
    /// Each finger's links and fingertip (`/scene/fingers/finger_<n>/{links,tip}`).
    pub const FINGERS: &str = "/scene/fingers";
    /// The desired rotation axis.
    pub const AXIS: &str = "/scene/rotation_axis";
    /// The wrench space (paper Fig. 9), in `(f_x, f_y, tau_z / rho)`.
    pub const WRENCH: &str = "/wrench_space";
    /// The grasp wrench space's hull.
    pub const GWS: &str = "/wrench_space/gws";
    /// The object wrench space scaled by alpha.
    pub const OWS: &str = "/wrench_space/ows_alpha";
    /// The contacts' primitive wrenches.
    pub const PRIMITIVE: &str = "/wrench_space/primitive_wrenches";
    /// The primitive wrenches of the ICR points.
    pub const CANDIDATES: &str = "/wrench_space/icr_wrenches";
    /// Angles (deg): `object` and `finger_<n>`.
    pub const ANGLES: &str = "/timeseries/angles";
    /// Quality: `alpha_star` (the grasp's, of the hand commands) and `alpha` (the margin).
    pub const QUALITY: &str = "/timeseries/quality";
    /// The plan phase as a number (0 start, 1 rolling, 2 attach, 3 detach, 4 done).
    pub const PHASE: &str = "/timeseries/phase";
    /// Latency (us) of the hand commands: `end_to_end`, `hop_*`, `compute_*`.
    pub const LATENCY: &str = "/timeseries/latency_us";
    /// Frames the visualizer dropped so far.
    pub const DROPPED: &str = "/timeseries/dropped_frames";
    /// One row per plan step taken up (its number), on the `step` timeline.
    pub const STEP: &str = "/plan/step";
    /// Phase changes and other events, as text.
    pub const EVENTS: &str = "/events";
}

/// The timeline of wall time since the run's start (seconds).
pub const TIME: &str = "time";
/// The timeline of plan steps.
pub const STEP: &str = "step";

/// A finger's state in a scene frame.
#[derive(Debug, Clone)]
pub struct FingerView {
    /// Finger number.
    pub finger: u32,
    /// Joint origins then the fingertip centre (hand frame).
    pub links: Vec<P3>,
    /// Fingertip centre and radius.
    pub tip: (P3, f32),
    /// The fingertip's angle around the object (deg).
    pub angle_deg: f64,
}

/// What the node sends the recording.
#[derive(Debug, Clone)]
pub enum Frame {
    /// The scene and the time series, at the visualizer's rate.
    Tick {
        /// Seconds since the start (none for a plan, which has steps only).
        t: Option<f64>,
        /// The object's translation and rotation `[x, y, z, w]`.
        pose: (P3, [f32; 4]),
        /// The object's rotation (deg, unwrapped).
        object_deg: f64,
        /// Contact points (hand frame).
        contacts: Vec<P3>,
        /// Friction-cone edges.
        cones: Vec<Vec<P3>>,
        /// The fingers.
        fingers: Vec<FingerView>,
        /// The smallest quality of the tracking commands since the last tick.
        quality: Option<f64>,
        /// The largest latencies since the last tick: end to end, three hops, three computes.
        latency: Option<[f64; 7]>,
        /// Frames dropped so far.
        dropped: u64,
    },
    /// A plan step taken up.
    Step {
        /// Seconds since the start (none for a plan).
        t: Option<f64>,
        /// Its number.
        step: u64,
        /// Its phase.
        phase: u32,
        /// Each finger's ICR (body frame) and whether the finger is in contact.
        icrs: Vec<(u32, bool, Vec<P3>)>,
        /// In an attach step: the attaching finger and the rendezvous region (body frame).
        rendezvous: Option<(u32, Vec<P3>)>,
        /// The grasp wrench space of its contacts.
        gws: Mesh,
        /// The contacts' primitive wrenches.
        primitive: Vec<P3>,
        /// The primitive wrenches of the contacts' ICR points.
        candidates: Vec<P3>,
    },
}

/// What the recording shows from the start.
pub struct Statics {
    /// The run's recording id (shared by every process that logs to it).
    pub recording_id: String,
    /// The object's surface (body frame).
    pub object: Mesh,
    /// The object wrench space scaled by alpha (its hull).
    pub ows: Mesh,
    /// The margin.
    pub alpha: f64,
    /// The desired rotation axis (hand frame) and where to draw it.
    pub axis: (P3, P3),
}

/// The layout the viewer opens with.
pub fn blueprint() -> Blueprint {
    Blueprint::new(
        Horizontal::new([
            Spatial3DView::new("Hand and object")
                .with_origin(paths::SCENE)
                .into(),
            Vertical::new([
                Spatial3DView::new("Wrench space (f_x, f_y, tau_z / rho)")
                    .with_origin(paths::WRENCH)
                    .into(),
                TimeSeriesView::new("Angles (deg)")
                    .with_origin(paths::ANGLES)
                    .into(),
                TimeSeriesView::new("Quality alpha* vs alpha")
                    .with_origin(paths::QUALITY)
                    .into(),
                TimeSeriesView::new("Phase")
                    .with_origin(paths::PHASE)
                    .into(),
                TimeSeriesView::new("Latency (us)")
                    .with_origin(paths::LATENCY)
                    .into(),
            ])
            .with_row_shares([3.0, 2.0, 2.0, 1.0, 2.0])
            .into(),
        ])
        .with_column_shares([3.0, 2.0]),
    )
}

/// The most recorded data Rerun's SDK holds before it blocks (the recording's memory bound).
pub const MAX_BYTES_IN_FLIGHT: u64 = 1 << 20;

/// Opens the recording. An `.rrd` gets Rerun's index footer when `footer` (the SDK then keeps
/// an entry per chunk in memory until the file is closed, ~1.3 GB an hour at the run's frame
/// rate; without it the file is still a valid recording, and `rerun rrd optimize` adds the
/// index afterwards).
pub fn open(recording: &Recording, id: &str, footer: bool) -> Result<rerun::RecordingStream> {
    // Rerun's queues are bounded by the bytes in flight: a viewer that lags then blocks this
    // thread, and the node drops frames, after at most this much memory.
    let batching = rerun::log::ChunkBatcherConfig {
        max_bytes_in_flight: MAX_BYTES_IN_FLIGHT,
        ..rerun::log::ChunkBatcherConfig::DEFAULT
    };
    let builder = rerun::RecordingStreamBuilder::new("icrflow")
        .recording_id(id)
        .batcher_config(batching)
        .with_blueprint(blueprint());
    match recording {
        Recording::Rrd(path) => {
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
            }
            let options = rerun::sink::FileSinkOptions {
                write_footer: footer,
            };
            let sink = rerun::sink::FileSink::with_options(path, options)
                .with_context(|| format!("cannot write the recording {}", path.display()))?;
            builder
                .set_sinks((sink,))
                .with_context(|| format!("cannot write the recording {}", path.display()))
        }
        Recording::Spawn(port) => {
            let url = format!("rerun+http://127.0.0.1:{port}/proxy");
            if !reachable("127.0.0.1", *port) {
                spawn_viewer(*port)?;
            }
            builder
                .connect_grpc_opts(url.clone())
                .with_context(|| format!("cannot connect to the spawned Rerun viewer at {url}"))
        }
        Recording::Connect(url) => {
            // Rerun's client retries an absent viewer for ever and then blocks: ask first.
            let (host, port) = icrflow_scenario::viewer_url(url)?;
            if !reachable(&host, port) {
                anyhow::bail!("no Rerun viewer at {url} (start one with `rerun`, or use --rrd)");
            }
            builder
                .connect_grpc_opts(url.clone())
                .with_context(|| format!("cannot connect to the Rerun viewer at {url}"))
        }
    }
}

/// Whether something accepts TCP connections at `host:port` (within 2 s).
fn reachable(host: &str, port: u16) -> bool {
    std::net::ToSocketAddrs::to_socket_addrs(&(host, port))
        .ok()
        .and_then(|mut a| a.next())
        .is_some_and(|a| std::net::TcpStream::connect_timeout(&a, Duration::from_secs(2)).is_ok())
}

/// Starts `rerun` (on the PATH) listening on 127.0.0.1 at `port` and waits until it accepts
/// connections. The viewer is the user's window, so it outlives the run: it gets a process
/// group of its own (a Ctrl-C of the run does not close it) and none of this process's output
/// (its logs would mix with the run's, and it would hold a caller's pipes open while it is
/// open). Rerun's SDK spawn inherits them, hence this.
fn spawn_viewer(port: u16) -> Result<()> {
    use std::os::unix::process::CommandExt as _;
    std::process::Command::new("rerun")
        .arg(format!("--port={port}"))
        .args(["--bind", "127.0.0.1", "--memory-limit=75%"])
        .args(["--hide-welcome-screen", "--expect-data-soon"])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .process_group(0)
        .spawn()
        .map_err(|e| {
            anyhow!(
                "cannot start a Rerun viewer (`rerun` 0.36 on the PATH: `pip install rerun-sdk==0.36.3`): {e}"
            )
        })?;
    let started = std::time::Instant::now();
    while !reachable("127.0.0.1", port) {
        if started.elapsed() > Duration::from_secs(20) {
            anyhow::bail!("the Rerun viewer started for the run does not listen on port {port}");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    Ok(())
}

fn mesh(m: &Mesh, rgba: u32) -> rerun::Mesh3D {
    rerun::Mesh3D::new(m.positions.iter().copied())
        .with_triangle_indices(m.triangles.iter().copied())
        .with_albedo_factor(rerun::Rgba32::from_u32(rgba))
}

/// Colour of finger `n`'s things.
fn finger_colour(n: u32) -> u32 {
    const COLOURS: [u32; 8] = [
        0xe6194bff, 0x3cb44bff, 0x4363d8ff, 0xf58231ff, 0x911eb4ff, 0x42d4f4ff, 0xf032e6ff,
        0xbfef45ff,
    ];
    COLOURS[n as usize % COLOURS.len()]
}

/// Logs the recording's static part.
pub fn statics(rec: &rerun::RecordingStream, s: &Statics) -> Result<()> {
    rec.log_static(paths::SCENE, &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
    rec.log_static(paths::OBJECT_MESH, &mesh(&s.object, 0xb0b0b0c0))?;
    rec.log_static(
        paths::AXIS,
        &rerun::Arrows3D::from_vectors([s.axis.1])
            .with_origins([s.axis.0])
            .with_colors([0xffd700ff]),
    )?;
    rec.log_static(paths::OWS, &mesh(&s.ows, 0x4363d860))?;
    let series = |path: &str, name: &str, rgba: u32| -> Result<()> {
        rec.log_static(
            path,
            &rerun::SeriesLines::new()
                .with_names([name])
                .with_colors([rerun::Color::from_u32(rgba)]),
        )?;
        Ok(())
    };
    series(
        &format!("{}/alpha_star", paths::QUALITY),
        "alpha*",
        0x3cb44bff,
    )?;
    series(&format!("{}/alpha", paths::QUALITY), "alpha", 0xe6194bff)?;
    series(&format!("{}/object", paths::ANGLES), "object", 0x000000ff)?;
    Ok(())
}

/// Logs frames until there are no more (the node closes the channel); returns the frames
/// logged.
pub fn log_frames(
    rec: &rerun::RecordingStream,
    alpha: f64,
    frames: impl IntoIterator<Item = Frame>,
) -> Result<u64> {
    let mut logged = 0;
    let mut step = 0i64;
    let mut phase = u32::MAX;
    for frame in frames {
        match frame {
            Frame::Tick {
                t,
                pose,
                object_deg,
                contacts,
                cones,
                fingers,
                quality,
                latency,
                dropped,
            } => {
                if let Some(t) = t {
                    rec.set_duration_secs(TIME, t);
                }
                rec.set_time_sequence(STEP, step);
                let (translation, [x, y, z, w]) = pose;
                rec.log(
                    paths::OBJECT,
                    &rerun::Transform3D::from_translation_rotation(
                        translation,
                        rerun::Quaternion::from_xyzw([x, y, z, w]),
                    ),
                )?;
                rec.log(
                    paths::CONTACTS,
                    &rerun::Points3D::new(contacts)
                        .with_radii([0.002])
                        .with_colors([0xff0000ff]),
                )?;
                rec.log(
                    paths::CONES,
                    &rerun::LineStrips3D::new(cones).with_colors([0xffa500ff]),
                )?;
                for f in &fingers {
                    let base = format!("{}/finger_{}", paths::FINGERS, f.finger);
                    rec.log(
                        format!("{base}/links"),
                        &rerun::LineStrips3D::new([f.links.clone()])
                            .with_radii([0.003])
                            .with_colors([finger_colour(f.finger)]),
                    )?;
                    rec.log(
                        format!("{base}/tip"),
                        &rerun::Ellipsoids3D::from_centers_and_radii([f.tip.0], [f.tip.1])
                            .with_colors([finger_colour(f.finger)])
                            .with_fill_mode(rerun::FillMode::Solid),
                    )?;
                    rec.log(
                        format!("{}/finger_{}", paths::ANGLES, f.finger),
                        &rerun::Scalars::single(f.angle_deg),
                    )?;
                }
                rec.log(
                    format!("{}/object", paths::ANGLES),
                    &rerun::Scalars::single(object_deg),
                )?;
                rec.log(
                    format!("{}/alpha", paths::QUALITY),
                    &rerun::Scalars::single(alpha),
                )?;
                if let Some(q) = quality {
                    rec.log(
                        format!("{}/alpha_star", paths::QUALITY),
                        &rerun::Scalars::single(q),
                    )?;
                }
                if let Some(l) = latency {
                    const NAMES: [&str; 7] = [
                        "end_to_end",
                        "hop_joint_state",
                        "hop_grasp_state",
                        "hop_wrench_space",
                        "compute_estimator",
                        "compute_wrench",
                        "compute_command",
                    ];
                    for (name, us) in NAMES.iter().zip(l) {
                        rec.log(
                            format!("{}/{name}", paths::LATENCY),
                            &rerun::Scalars::single(us),
                        )?;
                    }
                }
                rec.log(paths::DROPPED, &rerun::Scalars::single(dropped as f64))?;
            }
            Frame::Step {
                t,
                step: number,
                phase: p,
                icrs,
                rendezvous,
                gws,
                primitive,
                candidates,
            } => {
                step = i64::try_from(number).unwrap_or(i64::MAX);
                if let Some(t) = t {
                    rec.set_duration_secs(TIME, t);
                }
                rec.set_time_sequence(STEP, step);
                rec.log(paths::STEP, &rerun::Scalars::single(number as f64))?;
                rec.log(paths::PHASE, &rerun::Scalars::single(p as f64))?;
                if p != phase {
                    phase = p;
                    rec.log(
                        paths::EVENTS,
                        &rerun::TextLog::new(format!("step {number}: phase {}", phase_name(p))),
                    )?;
                }
                for (finger, in_contact, points) in &icrs {
                    let path = format!("{}/finger_{finger}", paths::ICR);
                    if *in_contact {
                        rec.log(
                            path,
                            &rerun::Points3D::new(points.iter().copied())
                                .with_radii([0.0015])
                                .with_colors([finger_colour(*finger)]),
                        )?;
                    } else {
                        rec.log(path, &rerun::Clear::flat())?;
                    }
                }
                match rendezvous {
                    Some((finger, points)) => {
                        rec.log(
                            paths::RENDEZVOUS,
                            &rerun::Points3D::new(points)
                                .with_radii([0.0025])
                                .with_colors([0xffd700ff]),
                        )?;
                        rec.log(
                            paths::EVENTS,
                            &rerun::TextLog::new(format!(
                                "step {number}: finger {finger} attaches in its rendezvous region"
                            )),
                        )?;
                    }
                    None => rec.log(paths::RENDEZVOUS, &rerun::Clear::flat())?,
                }
                rec.log(paths::GWS, &mesh(&gws, 0x3cb44b90))?;
                rec.log(
                    paths::PRIMITIVE,
                    &rerun::Points3D::new(primitive)
                        .with_radii([0.01])
                        .with_colors([0xff0000ff]),
                )?;
                rec.log(
                    paths::CANDIDATES,
                    &rerun::Points3D::new(candidates)
                        .with_radii([0.004])
                        .with_colors([0x80808080]),
                )?;
            }
        }
        logged += 1;
    }
    Ok(logged)
}

/// The phase's name.
pub fn phase_name(p: u32) -> &'static str {
    match p {
        0 => "start",
        1 => "rolling",
        2 => "attach",
        3 => "detach",
        4 => "done",
        _ => "unknown",
    }
}
