//! `[visualizer]`: the Rerun recording of a run ([`VisualizerSpec`]) and where it goes
//! ([`Recording`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::Real;

use crate::bounds;
use crate::raw::RawVisualizer;

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

pub(crate) fn visualizer_spec(raw: RawVisualizer, path: &Path) -> Result<VisualizerSpec> {
    let mode = raw.mode.unwrap_or_else(|| "rrd".into());
    let url = raw.url.unwrap_or_else(|| DEFAULT_VIEWER_URL.into());
    let (_, port) = viewer_url(&url).context("visualizer.url")?;
    if raw.rrd.is_some() && matches!(mode.as_str(), "spawn" | "connect") {
        bail!(
            "visualizer.rrd: the file of visualizer.mode = \"rrd\"; with mode = {mode:?} nothing is saved to it, so it has no effect: leave it out, or set mode = \"rrd\""
        );
    }
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
