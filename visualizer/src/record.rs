//! The recording: a thread of its own owns the Rerun stream and logs the frames the node
//! sends it, so that a lagging viewer (Rerun's SDK blocks when its bounded queues are full)
//! only ever blocks this thread; the node drops and counts the frames that find the queue full.

use std::time::Duration;

use crate::blueprint::Layout;
use crate::geometry::{Mesh, P3};
use anyhow::{Context as _, Result, anyhow};
use icrflow_scenario::Recording;

/// The entity paths of the recording (documented in the crate's README).
pub mod paths {
    /// The 3D scene, in the hand frame.
    pub const SCENE: &str = "/scene";
    /// The object's pose (its children are in its body frame).
    pub const OBJECT: &str = "/scene/object";
    /// The object's surface, painted by sectors of longitude.
    pub const OBJECT_MESH: &str = "/scene/object/mesh";
    /// The object's body x axis, turning with it.
    pub const OBJECT_MARKER: &str = "/scene/object/x_axis";
    /// Each finger's ICR (`/scene/object/icr/finger_<n>`), of the current plan step.
    pub const ICR: &str = "/scene/object/icr";
    /// The ICR a free finger attaches into during a switch (the rendezvous region), in each
    /// attach step; cleared otherwise.
    pub const RENDEZVOUS: &str = "/scene/object/rendezvous";
    /// The estimated contact points.
    pub const CONTACTS: &str = "/scene/contacts";
    /// The friction-cone edges at the contacts.
    pub const CONES: &str = "/scene/cones";
    /// With a simulated plant (MuJoCo): where the fingertips truly touch the object.
    pub const TRUE_CONTACTS: &str = "/scene/truth/contacts";
    /// With a simulated plant: the true contact forces on the object, as arrows
    /// ([`super::FORCE_SCALE`] m per N).
    pub const TRUE_FORCES: &str = "/scene/truth/forces";
    /// With a simulated plant: the object's true pose, as a frame (its axes drawn), beside
    /// the estimated one at [`OBJECT`].
    pub const TRUE_OBJECT: &str = "/scene/truth/object";
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
    /// The axes `f_x`, `f_y`, `tau_z / rho`, labelled.
    pub const WRENCH_AXES: &str = "/wrench_space/axes";
    /// The primitive wrenches of the ICR points.
    pub const CANDIDATES: &str = "/wrench_space/icr_wrenches";
    /// Angles (deg): `object` (estimated), `object_true` (with a simulated plant) and
    /// `finger_<n>`.
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

/// Length of a true contact force's arrow per newton (m).
pub const FORCE_SCALE: f32 = 0.01;

/// What a simulated plant knows to be true, in a scene frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthView {
    /// The contact points (hand frame).
    pub contacts: Vec<P3>,
    /// The force on the object at each (N, hand frame).
    pub forces: Vec<[f32; 3]>,
    /// The object's true rotation about z (deg, unwrapped).
    pub rotation_deg: f64,
    /// The object's true pose: its frame's translation and rotation (`x y z w`), hand frame.
    pub pose: (P3, [f32; 4]),
    /// Its rotation off the plan's axis since the start (deg): the swing of its swing-twist
    /// decomposition about the axis.
    pub tilt_deg: f64,
}

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
        /// The truth, with a simulated plant (the newest before the frame).
        truth: Option<TruthView>,
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
    /// Its colour per vertex.
    pub object_colours: Vec<u32>,
    /// The body x axis marker: origin and vector (body frame).
    pub marker: (P3, P3),
    /// The object wrench space scaled by alpha (its hull).
    pub ows: Mesh,
    /// The margin.
    pub alpha: f64,
    /// The desired rotation axis (hand frame) and where to draw it.
    pub axis: (P3, P3),
    /// The hand's fingers (their numbers).
    pub fingers: Vec<u32>,
    /// The viewer's layout.
    pub layout: Layout,
}

/// The most recorded data Rerun's SDK holds before it blocks (the recording's memory bound).
pub const MAX_BYTES_IN_FLIGHT: u64 = 1 << 20;

/// Opens the recording. An `.rrd` gets Rerun's index footer when `footer` (the SDK then keeps
/// an entry per chunk in memory until the file is closed, ~1.3 GB an hour at the run's frame
/// rate; without it the file is still a valid recording, and `rerun rrd optimize` adds the
/// index afterwards).
pub fn open(
    recording: &Recording,
    id: &str,
    footer: bool,
    layout: &Layout,
) -> Result<rerun::RecordingStream> {
    let rec = open_stream(recording, id, footer)?;
    // First in the stream, as `RecordingStreamBuilder::with_blueprint` sends it.
    crate::blueprint::send(&rec, APP, id, layout)?;
    Ok(rec)
}

/// The application id of every icrflow recording (the viewer keys blueprints by it).
pub const APP: &str = "icrflow";

fn open_stream(recording: &Recording, id: &str, footer: bool) -> Result<rerun::RecordingStream> {
    // Rerun's queues are bounded by the bytes in flight: a viewer that lags then blocks this
    // thread, and the node drops frames, after at most this much memory.
    let batching = rerun::log::ChunkBatcherConfig {
        max_bytes_in_flight: MAX_BYTES_IN_FLIGHT,
        ..rerun::log::ChunkBatcherConfig::DEFAULT
    };
    let builder = rerun::RecordingStreamBuilder::new(APP)
        .recording_id(id)
        .batcher_config(batching);
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

/// Colour of finger `n`'s things (bright enough for the viewer's dark background).
pub fn finger_colour(n: u32) -> u32 {
    const COLOURS: [u32; 8] = [
        0xff5c5cff, 0x5cd65cff, 0x5ca8ffff, 0xffa53dff, 0xd67cffff, 0x42d4f4ff, 0xf032e6ff,
        0xbfef45ff,
    ];
    COLOURS[n.saturating_sub(1) as usize % COLOURS.len()]
}

/// Colours of the wrench space (paper Fig. 9) and of the series, on the dark background.
pub mod colours {
    /// The grasp wrench space's hull: translucent green.
    pub const GWS: u32 = 0x3cc85a70;
    /// The alpha-scaled object wrench space: opaque gold, inside the GWS.
    pub const OWS: u32 = 0xffd23fff;
    /// The contacts' primitive wrenches.
    pub const PRIMITIVE: u32 = 0xff5c5cff;
    /// The ICR points' wrenches.
    pub const CANDIDATES: u32 = 0x42d4f4c0;
    /// The object's rotation in the angle plot.
    pub const OBJECT: u32 = 0xf5f5f5ff;
    /// alpha* in the quality plot.
    pub const ALPHA_STAR: u32 = 0x5cd65cff;
    /// alpha in the quality plot.
    pub const ALPHA: u32 = 0xff5c5cff;
    /// The phase plot.
    pub const PHASE: u32 = 0x8ab4ffff;
    /// The friction cones.
    pub const CONES: u32 = 0xffa53dff;
    /// The contacts.
    pub const CONTACTS: u32 = 0xffffffff;
    /// The true contacts and forces (a simulated plant's).
    pub const TRUTH: u32 = 0xff4fd8ff;
    /// The rendezvous region and the rotation axis.
    pub const RENDEZVOUS: u32 = 0xffd23fff;
}

/// The latency series, in the order of a frame's latencies.
const LATENCY_NAMES: [&str; 7] = [
    "end_to_end",
    "hop_joint_state",
    "hop_grasp_state",
    "hop_wrench_space",
    "compute_estimator",
    "compute_wrench",
    "compute_command",
];

/// Logs the recording's static part.
pub fn statics(rec: &rerun::RecordingStream, s: &Statics) -> Result<()> {
    rec.log_static(paths::SCENE, &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
    rec.log_static(
        paths::OBJECT_MESH,
        &rerun::Mesh3D::new(s.object.positions.iter().copied())
            .with_triangle_indices(s.object.triangles.iter().copied())
            .with_vertex_colors(s.object_colours.iter().copied()),
    )?;
    rec.log_static(
        paths::OBJECT_MARKER,
        &rerun::Arrows3D::from_vectors([s.marker.1])
            .with_origins([s.marker.0])
            .with_radii([0.0015])
            .with_colors([0xf2f2f2ff]),
    )?;
    rec.log_static(
        paths::AXIS,
        &rerun::Arrows3D::from_vectors([s.axis.1])
            .with_origins([s.axis.0])
            .with_colors([colours::RENDEZVOUS]),
    )?;
    rec.log_static(paths::OWS, &mesh(&s.ows, colours::OWS))?;
    rec.log_static(
        paths::WRENCH_AXES,
        &rerun::Arrows3D::from_vectors([[1.2, 0.0, 0.0], [0.0, 1.2, 0.0], [0.0, 0.0, 0.6]])
            .with_radii([0.006])
            .with_colors([0xff8080ff, 0x80ff80ff, 0x80b0ffff])
            .with_labels(["f_x", "f_y", "tau_z / rho"])
            .with_show_labels(true),
    )?;
    let series = |path: &str, name: &str, rgba: u32, width: f32| -> Result<()> {
        rec.log_static(
            path,
            &rerun::SeriesLines::new()
                .with_names([name])
                .with_colors([rerun::Color::from_u32(rgba)])
                .with_widths([width]),
        )?;
        Ok(())
    };
    series(
        &format!("{}/alpha_star", paths::QUALITY),
        "alpha*",
        colours::ALPHA_STAR,
        2.0,
    )?;
    series(
        &format!("{}/alpha", paths::QUALITY),
        "alpha",
        colours::ALPHA,
        1.5,
    )?;
    series(
        &format!("{}/object", paths::ANGLES),
        "object",
        colours::OBJECT,
        2.5,
    )?;
    for &f in &s.fingers {
        series(
            &format!("{}/finger_{f}", paths::ANGLES),
            &format!("finger {f}"),
            finger_colour(f),
            1.5,
        )?;
    }
    series(paths::PHASE, "phase", colours::PHASE, 2.0)?;
    if s.layout.run {
        const LATENCY: [u32; 7] = [
            0xf5f5f5ff, 0xff5c5cff, 0x5cd65cff, 0x5ca8ffff, 0xffa53dff, 0xd67cffff, 0x42d4f4ff,
        ];
        for (name, rgba) in LATENCY_NAMES.iter().zip(LATENCY) {
            series(&format!("{}/{name}", paths::LATENCY), name, rgba, 1.5)?;
        }
    }
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
    // Each fingertip's last angle, so that its series is continuous (unwrapped).
    let mut angles = std::collections::HashMap::<u32, f64>::new();
    for frame in frames {
        match frame {
            Frame::Tick {
                t,
                pose,
                object_deg,
                contacts,
                cones,
                fingers,
                truth,
                quality,
                latency,
                dropped,
            } => {
                if let Some(t) = t {
                    rec.set_duration_secs(TIME, t);
                }
                rec.set_time_sequence(STEP, step);
                log_object(rec, pose, contacts, cones)?;
                log_fingers(rec, &fingers, &mut angles)?;
                rec.log(
                    format!("{}/object", paths::ANGLES),
                    &rerun::Scalars::single(object_deg),
                )?;
                if let Some(truth) = truth {
                    log_truth(rec, truth)?;
                }
                log_signals(rec, alpha, quality, latency, dropped)?;
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
                        &rerun::TextLog::new(format!(
                            "step {number}: phase {}",
                            icrflow_interfaces::PlanPhase::name_of(p)
                        )),
                    )?;
                }
                log_regions(rec, number, &icrs, rendezvous)?;
                log_wrench_panel(rec, &gws, primitive, candidates)?;
            }
        }
        logged += 1;
    }
    Ok(logged)
}

/// A tick's object: its pose, the estimated contacts and their friction cones.
fn log_object(
    rec: &rerun::RecordingStream,
    pose: (P3, [f32; 4]),
    contacts: Vec<P3>,
    cones: Vec<Vec<P3>>,
) -> Result<()> {
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
            .with_radii([0.0025])
            .with_colors([colours::CONTACTS]),
    )?;
    rec.log(
        paths::CONES,
        &rerun::LineStrips3D::new(cones)
            .with_radii([0.0009])
            .with_colors([colours::CONES]),
    )?;
    Ok(())
}

/// A tick's fingers: links, fingertips, and each fingertip's angle, continued from `angles`
/// (each finger's last, unwrapped).
fn log_fingers(
    rec: &rerun::RecordingStream,
    fingers: &[FingerView],
    angles: &mut std::collections::HashMap<u32, f64>,
) -> Result<()> {
    for f in fingers {
        let base = format!("{}/finger_{}", paths::FINGERS, f.finger);
        rec.log(
            format!("{base}/links"),
            &rerun::LineStrips3D::new([f.links.clone()])
                .with_radii([0.003])
                .with_colors([finger_colour(f.finger)]),
        )?;
        // Translucent: the contact, its cone and the ICR show through.
        rec.log(
            format!("{base}/tip"),
            &rerun::Ellipsoids3D::from_centers_and_radii([f.tip.0], [f.tip.1])
                .with_colors([finger_colour(f.finger) & 0xffffff00 | 0x50])
                .with_fill_mode(rerun::FillMode::Solid),
        )?;
        let angle = match angles.get(&f.finger) {
            Some(&last) => crate::geometry::unwrap_deg(last, f.angle_deg),
            None => f.angle_deg,
        };
        angles.insert(f.finger, angle);
        rec.log(
            format!("{}/finger_{}", paths::ANGLES, f.finger),
            &rerun::Scalars::single(angle),
        )?;
    }
    Ok(())
}

/// A tick's ground truth (a physics plant's): the true contacts, forces and rotation.
fn log_truth(rec: &rerun::RecordingStream, truth: TruthView) -> Result<()> {
    rec.log(
        paths::TRUE_CONTACTS,
        &rerun::Points3D::new(truth.contacts.iter().copied())
            .with_radii([0.0018])
            .with_colors([colours::TRUTH]),
    )?;
    rec.log(
        paths::TRUE_FORCES,
        &rerun::Arrows3D::from_vectors(
            truth
                .forces
                .iter()
                .map(|f| [f[0] * FORCE_SCALE, f[1] * FORCE_SCALE, f[2] * FORCE_SCALE]),
        )
        .with_origins(truth.contacts)
        .with_radii([0.0008])
        .with_colors([colours::TRUTH]),
    )?;
    rec.log(
        format!("{}/object_true", paths::ANGLES),
        &rerun::Scalars::single(truth.rotation_deg),
    )?;
    rec.log(
        format!("{}/object_tilt", paths::ANGLES),
        &rerun::Scalars::single(truth.tilt_deg),
    )?;
    let (translation, [x, y, z, w]) = truth.pose;
    rec.log(
        paths::TRUE_OBJECT,
        &[
            &rerun::Transform3D::from_translation_rotation(
                translation,
                rerun::Quaternion::from_xyzw([x, y, z, w]),
            ) as &dyn rerun::AsComponents,
            &rerun::TransformAxes3D::new(0.03),
        ],
    )?;
    Ok(())
}

/// A tick's time series: the margin and alpha*, the latencies, the frames dropped.
fn log_signals(
    rec: &rerun::RecordingStream,
    alpha: f64,
    quality: Option<f64>,
    latency: Option<[f64; 7]>,
    dropped: u64,
) -> Result<()> {
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
        for (name, us) in LATENCY_NAMES.iter().zip(l) {
            rec.log(
                format!("{}/{name}", paths::LATENCY),
                &rerun::Scalars::single(us),
            )?;
        }
    }
    rec.log(paths::DROPPED, &rerun::Scalars::single(dropped as f64))?;
    Ok(())
}

/// A plan step's regions: each finger's ICR (cleared for a finger not in contact) and, in an
/// attach step, the attaching finger's rendezvous region, said in the events.
fn log_regions(
    rec: &rerun::RecordingStream,
    number: u64,
    icrs: &[(u32, bool, Vec<P3>)],
    rendezvous: Option<(u32, Vec<P3>)>,
) -> Result<()> {
    for (finger, in_contact, points) in icrs {
        let path = format!("{}/finger_{finger}", paths::ICR);
        if *in_contact {
            rec.log(
                path,
                &rerun::Points3D::new(points.iter().copied())
                    .with_radii([0.0028])
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
                    .with_radii([0.0035])
                    .with_colors([colours::RENDEZVOUS]),
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
    Ok(())
}

/// A plan step's wrench panel: the grasp wrench space's hull, its primitive wrenches and the
/// candidates' wrenches.
fn log_wrench_panel(
    rec: &rerun::RecordingStream,
    gws: &Mesh,
    primitive: Vec<P3>,
    candidates: Vec<P3>,
) -> Result<()> {
    rec.log(paths::GWS, &mesh(gws, colours::GWS))?;
    rec.log(
        paths::PRIMITIVE,
        &rerun::Points3D::new(primitive)
            .with_radii([0.02])
            .with_colors([colours::PRIMITIVE]),
    )?;
    rec.log(
        paths::CANDIDATES,
        &rerun::Points3D::new(candidates)
            .with_radii([0.008])
            .with_colors([colours::CANDIDATES]),
    )?;
    Ok(())
}
