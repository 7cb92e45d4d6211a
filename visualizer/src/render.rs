//! The visualizer's render mode: `icrflow-visualizer --render RRD --at END|STEP --out PNG
//! --size WxH --viewer RERUN`, started by `icrflow render`. It renders a recording as the
//! Rerun viewer shows it, at a plan step or at the end, into a PNG, headless.
//!
//! The viewer (`rerun --headless`, software Vulkan where there is no GPU) loads the file and
//! serves its gRPC control service (`rerun.sdk_comms.v1alpha1.ViewerControlService`, the one
//! the Python SDK's `ViewerClient.save_screenshot` uses) on a free loopback port. Through it
//! this mode waits until the file is loaded (the recording's timelines have stopped growing:
//! `rerun --screenshot-to` shoots while the file is still loading), moves the time cursor to
//! the step (on the `step` timeline) or to the end (the `time` timeline of a run, the `step`
//! timeline of a plan), paused, and asks for the screenshot.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, anyhow, bail};
use re_protos::common::v1alpha1::{StoreId, StoreKind, Timeline, TimelineTime};
use re_protos::sdk_comms::v1alpha1::viewer_control_service_client::ViewerControlServiceClient;
use re_protos::sdk_comms::v1alpha1::{
    GetViewerStateRequest, SaveScreenshotRequest, SetTimeCursorRequest, ViewerRecording,
};

use crate::record::{STEP, TIME};

/// Where in the recording to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum At {
    /// The end: the last time of a run, the last step of a plan.
    End,
    /// A plan step (the state when the step was the newest taken up).
    Step(i64),
}

impl At {
    /// `END` (any case) or a step number.
    pub fn parse(text: &str) -> Result<Self> {
        if text.eq_ignore_ascii_case("end") {
            return Ok(Self::End);
        }
        match text.parse::<i64>() {
            Ok(step) if step >= 0 => Ok(Self::Step(step)),
            _ => bail!("--at {text:?}: expected END or a plan step number (0, 1, ...)"),
        }
    }
}

/// A window size `WxH` in logical points, each 64 to 8192.
pub fn parse_size(text: &str) -> Result<(u32, u32)> {
    let bad = || anyhow!("--size {text:?}: expected WIDTHxHEIGHT, e.g. 1280x720 (64 to 8192 each)");
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if !((64..=8192).contains(&w) && (64..=8192).contains(&h)) {
        return Err(bad());
    }
    Ok((w, h))
}

/// What to render: the render mode's arguments (`RRD --at END|STEP --out PNG --size WxH
/// --viewer RERUN`), parsed by clap in the visualizer's command line.
#[derive(Debug, Clone, clap::Args)]
pub struct Request {
    /// The recording.
    #[arg(value_name = "RRD")]
    pub rrd: PathBuf,
    /// Where in it: END, or a plan step.
    #[arg(long, value_name = "END|STEP", default_value = "END", value_parser = At::parse)]
    pub at: At,
    /// The PNG to write.
    #[arg(long, value_name = "PNG")]
    pub out: PathBuf,
    /// The window size (logical points), WIDTHxHEIGHT.
    #[arg(long, value_name = "WxH", default_value = "1280x720", value_parser = parse_size)]
    pub size: (u32, u32),
    /// The `rerun` executable (0.36).
    #[arg(long, value_name = "RERUN")]
    pub viewer: PathBuf,
}

/// The viewer process (in a process group of its own: `rerun` from pip is a launcher that
/// starts the viewer as its child), ended with its group when dropped.
struct Viewer {
    child: Child,
    log: PathBuf,
}

impl Viewer {
    /// What the viewer wrote on stderr, its last lines.
    fn log_tail(&self) -> String {
        let text = std::fs::read_to_string(&self.log).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(12)..].join("\n")
    }

    /// An error if the viewer has exited.
    fn check_alive(&mut self) -> Result<()> {
        if let Some(status) = self.child.try_wait().context("waiting for the viewer")? {
            bail!("the Rerun viewer exited ({status}):\n{}", self.log_tail());
        }
        Ok(())
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        use nix::sys::signal::{Signal, killpg};
        use nix::unistd::Pid;
        let group = Pid::from_raw(self.child.id() as i32);
        let _ = killpg(group, Signal::SIGTERM);
        let started = Instant::now();
        while started.elapsed() < Duration::from_secs(3) {
            if matches!(self.child.try_wait(), Ok(Some(_))) {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = killpg(group, Signal::SIGKILL);
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.log);
    }
}

/// A free TCP port on the loopback interface.
fn free_port() -> Result<u16> {
    let listener =
        std::net::TcpListener::bind("127.0.0.1:0").context("finding a free loopback port")?;
    Ok(listener.local_addr()?.port())
}

/// The longest the viewer may take to answer, to load the file, and to write the picture
/// (software rendering on a busy machine is slow; these only bound a viewer that hangs).
const PATIENCE: Duration = Duration::from_secs(180);

/// How many polls in a row (a quarter of a second apart) must see the recording's timelines
/// unchanged before the file counts as loaded.
const SETTLED_POLLS: u32 = 8;

/// Renders the recording at the chosen step or end into the PNG.
pub fn run(req: &Request) -> Result<()> {
    if !req.rrd.is_file() {
        bail!("no recording at {}", req.rrd.display());
    }
    let rrd = std::fs::canonicalize(&req.rrd)
        .with_context(|| format!("cannot read {}", req.rrd.display()))?;
    // A file the viewer cannot read would leave it waiting for data until PATIENCE: refuse it
    // by its header (every Rerun 0.36 file starts with `RRF2`).
    let mut head = [0u8; 4];
    let read = std::fs::File::open(&rrd)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok();
    if !read || &head != b"RRF2" {
        bail!(
            "{} is not a Rerun recording: it does not start with the RRF2 header of Rerun 0.36 files",
            rrd.display()
        );
    }
    let out = absolute(&req.out)?;
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let tmp = out.with_extension("png.tmp.png");
    let _ = std::fs::remove_file(&tmp);
    let port = free_port()?;
    let log =
        std::env::temp_dir().join(format!("icrflow-render-{}-{port}.log", std::process::id()));
    let stderr =
        std::fs::File::create(&log).with_context(|| format!("creating {}", log.display()))?;
    let mut viewer = {
        use std::os::unix::process::CommandExt as _;
        let child = Command::new(&req.viewer)
            .args(["--headless", "--bind", "127.0.0.1", "--port"])
            .arg(port.to_string())
            .arg("--window-size")
            .arg(format!("{}x{}", req.size.0, req.size.1))
            .args(["--hide-welcome-screen", "--memory-limit", "50%"])
            .arg(&rrd)
            .env("RUST_LOG", "warn")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(stderr)
            .process_group(0)
            .spawn()
            .with_context(|| format!("cannot start the Rerun viewer {}", req.viewer.display()))?;
        Viewer { child, log }
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the gRPC client")?;
    let url = format!("http://127.0.0.1:{port}");
    let started = Instant::now();
    let mut client = loop {
        viewer.check_alive()?;
        let endpoint = tonic::transport::Endpoint::from_shared(url.clone())?;
        if let Ok(channel) = runtime.block_on(endpoint.connect()) {
            break ViewerControlServiceClient::new(channel).max_decoding_message_size(64 << 20);
        }
        if started.elapsed() > PATIENCE {
            bail!(
                "the Rerun viewer did not listen on port {port}:\n{}",
                viewer.log_tail()
            );
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    // Loaded: the recording's timelines unchanged over SETTLED_POLLS polls.
    let mut last: Option<ViewerRecording> = None;
    let mut settled = 0;
    let recording = loop {
        viewer.check_alive()?;
        if started.elapsed() > PATIENCE {
            bail!(
                "the Rerun viewer did not finish loading {} in {} s",
                rrd.display(),
                PATIENCE.as_secs()
            );
        }
        std::thread::sleep(Duration::from_millis(250));
        let state = match runtime.block_on(client.get_viewer_state(GetViewerStateRequest {})) {
            Ok(s) => s.into_inner(),
            Err(_) => continue,
        };
        let now = state.recordings.into_iter().find(|r| {
            r.store_id
                .as_ref()
                .is_some_and(|s| s.kind == StoreKind::Recording as i32)
                && !r.timelines.is_empty()
        });
        match (&now, &last) {
            (Some(a), Some(b)) if a.timelines == b.timelines => settled += 1,
            _ => settled = 0,
        }
        last = now;
        if settled >= SETTLED_POLLS
            && let Some(r) = last.take()
        {
            break r;
        }
    };
    let range = |name: &str| {
        recording.timelines.iter().find_map(|t| {
            (t.timeline.as_ref().is_some_and(|x| x.name == name))
                .then_some(t.time_range.as_ref().map(|r| (r.start, r.end)))
                .flatten()
        })
    };
    let steps = range(STEP).with_context(|| {
        format!(
            "{} has no `{STEP}` timeline: not a recording of `icrflow run` or `icrflow plan`",
            rrd.display()
        )
    })?;
    let (timeline, time) = match req.at {
        At::Step(s) if s < steps.0 || s > steps.1 => bail!(
            "step {s} is not in the recording: its steps are {} to {}",
            steps.0,
            steps.1
        ),
        At::Step(s) => (STEP, s),
        At::End => match range(TIME) {
            Some((_, end)) => (TIME, end),
            None => (STEP, steps.1),
        },
    };
    let store: Option<StoreId> = recording.store_id.clone();
    runtime
        .block_on(client.set_time_cursor(SetTimeCursorRequest {
            store_id: store,
            timeline: Some(Timeline {
                name: timeline.to_string(),
            }),
            time: Some(TimelineTime { time }),
            play: false,
        }))
        .map_err(|e| {
            anyhow!(
                "the Rerun viewer refused to move its time cursor: {}",
                e.message()
            )
        })?;
    // A few frames at the new time before the picture (the plots and the scene follow the
    // cursor on the next frame; asking twice gives the viewer two frames).
    for _ in 0..2 {
        let _ = runtime.block_on(client.get_viewer_state(GetViewerStateRequest {}));
        std::thread::sleep(Duration::from_millis(300));
    }
    runtime
        .block_on(client.save_screenshot(SaveScreenshotRequest {
            view_id: None,
            file_path: tmp.display().to_string(),
        }))
        .map_err(|e| {
            anyhow!(
                "the Rerun viewer could not take the screenshot: {}",
                e.message()
            )
        })?;
    let shot = Instant::now();
    while !tmp.is_file() || std::fs::metadata(&tmp).map_or(0, |m| m.len()) == 0 {
        viewer.check_alive()?;
        if shot.elapsed() > PATIENCE {
            bail!("the Rerun viewer did not write {}", tmp.display());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    // Written once it no longer grows.
    let mut size = 0;
    loop {
        std::thread::sleep(Duration::from_millis(300));
        let now = std::fs::metadata(&tmp).map_or(0, |m| m.len());
        if now == size {
            break;
        }
        size = now;
    }
    drop(viewer);
    std::fs::rename(&tmp, &out).with_context(|| format!("cannot write {}", out.display()))?;
    let at = match req.at {
        At::End => format!("the end ({timeline} {})", shown(timeline, time)),
        At::Step(s) => format!("step {s}"),
    };
    eprintln!(
        "icrflow-visualizer: rendered {} at {at} into {}",
        rrd.display(),
        out.display()
    );
    Ok(())
}

/// A time on `timeline` as the viewer shows it: seconds for `time`, the number for `step`.
fn shown(timeline: &str, time: i64) -> String {
    if timeline == TIME {
        format!("{:.2} s", time as f64 * 1e-9)
    } else {
        time.to_string()
    }
}

/// `path` made absolute (the viewer writes the picture relative to its own directory).
fn absolute(path: &Path) -> Result<PathBuf> {
    std::path::absolute(path).with_context(|| format!("cannot resolve {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_arguments_are_read_or_refused_by_name() {
        assert_eq!(At::parse("END").unwrap(), At::End);
        assert_eq!(At::parse("end").unwrap(), At::End);
        assert_eq!(At::parse("42").unwrap(), At::Step(42));
        for bad in ["-1", "x", "", "4.5"] {
            let e = At::parse(bad).unwrap_err().to_string();
            assert!(e.contains("--at") && e.contains("END"), "{e}");
        }
        assert_eq!(parse_size("1280x720").unwrap(), (1280, 720));
        for bad in ["1280", "0x720", "1280x", "axb", "100000x10"] {
            let e = parse_size(bad).unwrap_err().to_string();
            assert!(e.contains("--size") && e.contains("WIDTHxHEIGHT"), "{e}");
        }
        #[derive(Debug, clap::Parser)]
        #[command(no_binary_name = true)]
        struct Cli {
            #[command(flatten)]
            request: Request,
        }
        let args = ["r.rrd", "--at", "7", "--out", "p.png", "--viewer", "rerun"];
        let r = <Cli as clap::Parser>::try_parse_from(args).unwrap().request;
        assert_eq!((r.at, r.size), (At::Step(7), (1280, 720)));
        let e = <Cli as clap::Parser>::try_parse_from(&args[..5])
            .unwrap_err()
            .to_string();
        assert!(e.contains("--viewer <RERUN>"), "{e}");
        let e = <Cli as clap::Parser>::try_parse_from([
            "r.rrd", "--at", "x", "--out", "p.png", "--viewer", "v",
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("--at") && e.contains("END"), "{e}");
    }
}
