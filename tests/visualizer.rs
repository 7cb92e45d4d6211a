//! The Rerun visualizer (issue #6), end to end: a real `icrflow run` of the paper scenario
//! records to an `.rrd`, which the Python Rerun SDK of the same version reads back
//! (tests/read_rrd.py) and the `rerun` viewer of the same version renders headless.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use std::net::TcpListener;
use std::os::unix::process::CommandExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::{python, root, scratch};

/// One pipeline at a time.
static PIPELINE: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The entity paths the recording documents (visualizer/README.md), for the paper's hand
/// (fingers 1 to 4; finger 3 starts free).
const ENTITIES: [&str; 19] = [
    "/scene",
    "/scene/object",
    "/scene/object/mesh",
    "/scene/object/icr/finger_1",
    "/scene/object/rendezvous",
    "/scene/contacts",
    "/scene/cones",
    "/scene/fingers/finger_1/links",
    "/scene/fingers/finger_3/tip",
    "/scene/rotation_axis",
    "/wrench_space/gws",
    "/wrench_space/ows_alpha",
    "/wrench_space/primitive_wrenches",
    "/wrench_space/icr_wrenches",
    "/timeseries/angles/object",
    "/timeseries/angles/finger_2",
    "/timeseries/quality/alpha_star",
    "/timeseries/phase",
    "/timeseries/latency_us/end_to_end",
];

/// The paper scenario without the Zenoh bridge (it is not what is tested), with `extra`
/// appended, as `dir/name.toml`.
fn config(dir: &Path, name: &str, extra: &str) -> PathBuf {
    let good = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!("{good}\n[zenoh]\nenabled = false\n{extra}\n"),
    )
    .unwrap();
    path
}

/// `icrflow run CONFIG --summary-json` with `args`: its exit success, stderr and summary.
fn run(config: &Path, args: &[&str]) -> (bool, String, serde_json::Value) {
    run_with_path(config, args, None)
}

/// [`run`] with `dir` first on the PATH.
fn run_with_path(
    config: &Path,
    args: &[&str],
    dir: Option<&Path>,
) -> (bool, String, serde_json::Value) {
    let summary = config.with_extension("json");
    let mut command = Command::new(env!("CARGO_BIN_EXE_icrflow"));
    if let Some(dir) = dir {
        let path = std::env::var_os("PATH").unwrap_or_default();
        let mut dirs = vec![dir.to_path_buf()];
        dirs.extend(std::env::split_paths(&path));
        command.env("PATH", std::env::join_paths(dirs).unwrap());
    }
    let out = command
        .args(["run", config.to_str().unwrap(), "--summary-json"])
        .arg(&summary)
        .args(args)
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err =
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
    let s = serde_json::from_slice(&std::fs::read(&summary).unwrap_or_default())
        .unwrap_or(serde_json::Value::Null);
    (out.status.success(), err, s)
}

/// What the Python Rerun SDK reads in `rrd` (tests/read_rrd.py), checked against what a run's
/// or a plan's summary `s` says: the minimum of the quality series equal to the summary's, and
/// the rendezvous region shown, not empty, in exactly the attach steps (phase 2), one per
/// finger switch of the summary.
fn read_rrd(rrd: &Path, s: &serde_json::Value) -> serde_json::Value {
    let r = json_of(
        Command::new(python())
            .arg(root().join("tests/read_rrd.py"))
            .arg(rrd),
    );
    let logged = r["quality_min"].as_f64().unwrap();
    let min_quality = s["min_quality"].as_f64().unwrap();
    assert!(
        (logged - min_quality).abs() <= 1e-12,
        "{logged} vs {min_quality}"
    );
    let steps_where = |key: &str, keep: &dyn Fn(f64) -> bool| -> Vec<u64> {
        r[key]
            .as_array()
            .unwrap()
            .iter()
            .filter(|row| keep(row[1].as_f64().unwrap()))
            .map(|row| row[0].as_u64().unwrap())
            .collect()
    };
    let attach = steps_where("phases", &|p| p == 2.0);
    let rendezvous = steps_where("rendezvous", &|points| points > 0.0);
    assert_eq!(attach.len() as u64, s["switches"].as_u64().unwrap(), "{r}");
    assert!(!attach.is_empty(), "{s}");
    assert_eq!(rendezvous, attach, "rendezvous shown in the attach steps");
    r
}

/// [`read_rrd`] for a run with summary `s`: also the run's recording id, and one `/plan/step`
/// row per step (each once, as many as the summary's steps).
fn read_back(rrd: &Path, s: &serde_json::Value) -> serde_json::Value {
    let r = read_rrd(rrd, s);
    assert_eq!(
        r["recording_ids"],
        serde_json::json!([s["recording"]["id"]]),
        "{r}"
    );
    let steps: Vec<u64> = r["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as u64)
        .collect();
    let summary_steps = s["steps"].as_u64().unwrap();
    assert!(summary_steps > 50, "{s}");
    assert_eq!(
        steps.iter().filter(|&&k| k > 0).count() as u64,
        summary_steps,
        "{steps:?}"
    );
    assert_eq!(steps.iter().max().copied(), Some(summary_steps));
    assert!(
        steps.windows(2).all(|w| w[0] < w[1]),
        "each once: {steps:?}"
    );
    r
}

/// What `command` prints on stdout, as JSON, once it has succeeded.
fn json_of(command: &mut Command) -> serde_json::Value {
    let out = command.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Kills process group `pgid` (SIGKILL), then waits until its leader is gone.
fn kill_group(pgid: u32) {
    let _ = Command::new("kill")
        .args(["-KILL", "--", &format!("-{pgid}")])
        .stderr(Stdio::null())
        .status();
    for _ in 0..50 {
        let alive = std::fs::read_to_string(format!("/proc/{pgid}/stat")).is_ok_and(|s| {
            !s.rsplit(')')
                .next()
                .unwrap_or("")
                .trim_start()
                .starts_with('Z')
        });
        if !alive {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}

/// The `rerun` viewer/CLI of the test venv (beside its Python).
fn rerun() -> PathBuf {
    Path::new(&python()).with_file_name("rerun")
}

#[test]
fn a_run_records_what_its_summary_says_and_the_viewer_renders_it() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("visualizer");
    let rrd = dir.join("paper.rrd");
    let (ok, err, s) = run(
        &config(&dir, "paper", ""),
        &["--rrd", rrd.to_str().unwrap()],
    );
    assert!(ok, "{err}");
    assert_eq!(s["completed"], true, "{s}");
    let rec = &s["recording"];
    assert_eq!(rec["target"], rrd.display().to_string(), "{s}");
    assert!(rec["frames"].as_u64().unwrap() > 100, "{s}");
    assert!(
        err.contains(&format!("saved to {}", rrd.display())),
        "the path is printed at the end: {err}"
    );

    // Read back by the Rerun SDK of the same version: the run's id, one row per plan step
    // (as many as the summary's steps), the quality the hand commands tracked with.
    let r = read_back(&rrd, &s);
    let entities: Vec<&str> = r["entities"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_str().unwrap())
        .collect();
    for e in ENTITIES {
        assert!(entities.contains(&e), "{e} missing: {entities:?}");
    }
    assert_eq!(r["alpha"], serde_json::json!([s["alpha"]]));

    // It opens with the paper's layout, the latency row included.
    let b = blueprint(&rrd);
    assert!(view_names(&b).contains(&LATENCY.to_string()), "{b}");

    // `icrflow render` draws it headless (software Vulkan) at the end and at the start: each
    // picture is not blank, and the end differs from the start.
    let end = dir.join("end.png");
    let start = dir.join("start.png");
    render(&rrd, "END", &end);
    render(&rrd, "0", &start);
    let png = png_stats(&end, Some(&start));
    assert_eq!(
        (png["width"].as_u64(), png["height"].as_u64()),
        (Some(1280), Some(720))
    );
    assert!(png["colours"].as_u64().unwrap() > 100, "{png}");
    assert!(png_stats(&start, None)["colours"].as_u64().unwrap() > 100);
    let changed = png["changed"].as_f64().unwrap();
    assert!(changed > 0.02, "the end looks like the start: {png}");

    // A step beyond the recording is refused, naming the recording's steps.
    let last = s["steps"].as_u64().unwrap();
    let out = icrflow(
        &[
            "render",
            rrd.to_str().unwrap(),
            "--at",
            &(last + 5).to_string(),
            "--out",
        ],
        &dir.join("x.png"),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains(&format!("step {}", last + 5)) && err.contains(&format!("0 to {last}")),
        "{err}"
    );
    assert!(!dir.join("x.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The views (names, classes, origins), 3D eyes and panel states of the recording's blueprint
/// (tests/read_rrd.py --blueprint), checked against the layout every recording has: the hand
/// seen from the top, the wrench space, the angle, quality and phase plots, the blueprint and
/// selection panels collapsed.
fn blueprint(rrd: &Path) -> serde_json::Value {
    let b = json_of(
        Command::new(python())
            .arg(root().join("tests/read_rrd.py"))
            .arg("--blueprint")
            .arg(rrd),
    );
    let views = b["views"].as_array().unwrap();
    let find = |name: &str| {
        views
            .iter()
            .find(|v| v["name"] == name)
            .unwrap_or_else(|| panic!("no view {name:?}: {b}"))
    };
    for (name, class, origin) in [
        (HAND, "3D", "/scene"),
        (WRENCH, "3D", "/wrench_space"),
        (ANGLES, "TimeSeries", "/timeseries/angles"),
        (QUALITY, "TimeSeries", "/timeseries/quality"),
        (PHASE, "TimeSeries", "/timeseries/phase"),
    ] {
        let v = find(name);
        assert_eq!(
            (v["class"].as_str(), v["origin"].as_str()),
            (Some(class), Some(origin)),
            "{v}"
        );
    }
    // The hand is seen from the top: the eye above the hand frame's origin, looking at it.
    let eye = &b["eyes"][HAND];
    let at = |k: &str| -> Vec<f64> {
        eye[k]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (p, t) = (at("position"), at("look_target"));
    assert!(
        p[0].abs() < 1e-6 && p[1].abs() < 1e-6 && p[2] > 0.1,
        "{eye}"
    );
    assert_eq!(t, vec![0.0, 0.0, 0.0], "{eye}");
    assert_eq!(b["panels"]["selection_panel"], "collapsed", "{b}");
    assert_eq!(b["panels"]["blueprint_panel"], "collapsed", "{b}");
    b
}

/// The names of the blueprint's views.
fn view_names(b: &serde_json::Value) -> Vec<String> {
    b["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap_or_default().to_string())
        .collect()
}

/// The views' names (visualizer/src/blueprint.rs).
const HAND: &str = "Hand and object (top view)";
const WRENCH: &str = "Wrench space: GWS green, alpha OWS gold";
const ANGLES: &str = "Angles (deg): object (white), fingertips";
const QUALITY: &str = "Quality: alpha* (green) vs alpha (red)";
const PHASE: &str = "Phase: 1 rolling, 2 attach, 3 detach, 4 done";
const LATENCY: &str = "Latency (us)";

/// `icrflow ARGS OUT` (the test venv's viewer through ICRFLOW_PYTHON).
fn icrflow(args: &[&str], out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(args)
        .arg(out)
        .env("ICRFLOW_PYTHON", python())
        .current_dir(root())
        .output()
        .unwrap()
}

/// `icrflow render RRD --at AT --out PNG`, which must succeed and write the picture.
fn render(rrd: &Path, at: &str, png: &Path) {
    let out = icrflow(&["render", rrd.to_str().unwrap(), "--at", at, "--out"], png);
    assert!(
        out.status.success(),
        "render --at {at}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(png.is_file(), "{}", png.display());
}

/// tests/read_rrd.py --png: the picture's size and colours, and how much of it differs from
/// `other`.
fn png_stats(png: &Path, other: Option<&Path>) -> serde_json::Value {
    let mut command = Command::new(python());
    command
        .arg(root().join("tests/read_rrd.py"))
        .arg("--png")
        .arg(png);
    if let Some(other) = other {
        command.arg(other);
    }
    json_of(&mut command)
}

#[test]
fn render_refuses_bad_input_by_name() {
    let dir = scratch("visualizer-render-bad");
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("x.png");
    // The project's venv (scripts/setup-python.sh's, where the test venv's Python is).
    let python = python();
    let cache = Path::new(&python).ancestors().nth(3).unwrap().to_path_buf();
    let run_in = |args: &[&str], env_path: Option<&str>, cache: &Path| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_icrflow"));
        c.args(args).arg("--out").arg(&png).current_dir(root());
        match env_path {
            // Neither $ICRFLOW_PYTHON nor the PATH: the project's venv under `cache` (or none).
            Some(p) => {
                c.env("PATH", p)
                    .env_remove("ICRFLOW_PYTHON")
                    .env("ICRFLOW_CACHE", cache)
                    .env("HOME", cache);
            }
            None => {
                c.env("ICRFLOW_PYTHON", &python);
            }
        }
        let out = c.output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let run = |args: &[&str], env_path: Option<&str>| run_in(args, env_path, &dir);
    let missing = dir.join("missing.rrd");
    let err = run(&["render", missing.to_str().unwrap()], None);
    assert!(
        err.contains("no recording at") && err.contains("missing.rrd"),
        "{err}"
    );
    // Any file will do for the argument checks: they come before the file is read.
    let rrd = dir.join("some.rrd");
    std::fs::write(&rrd, b"not a recording").unwrap();
    let rrd = rrd.to_str().unwrap();
    let err = run(&["render", rrd, "--size", "1280"], None);
    assert!(
        err.contains("--size") && err.contains("WIDTHxHEIGHT"),
        "{err}"
    );
    let err = run(&["render", rrd, "--at", "last"], None);
    assert!(err.contains("--at") && err.contains("END"), "{err}");
    let err = run(&["render", rrd], Some(dir.to_str().unwrap()));
    assert!(
        err.contains("no Rerun viewer") && err.contains("rerun-sdk==0.36.3"),
        "{err}"
    );
    // The error names where it looked: the project's venv under ICRFLOW_CACHE, the PATH.
    let venv = dir.join("venv/bin/rerun");
    assert!(
        err.contains(&venv.display().to_string()) && err.contains("the PATH (1 directories)"),
        "{err}"
    );
    // The viewer scripts/setup.sh installed into the project's venv is found without
    // ICRFLOW_PYTHON or the PATH: the render goes on to read the file.
    let err = run_in(&["render", rrd], Some(dir.to_str().unwrap()), &cache);
    assert!(
        err.contains("is not a Rerun recording") && err.contains("some.rrd"),
        "{err}"
    );
    let err = run(&["render", rrd], None);
    assert!(
        err.contains("is not a Rerun recording") && err.contains("some.rrd"),
        "{err}"
    );
    assert!(!png.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_viewer_that_does_not_read_costs_dropped_frames_not_the_loop() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("visualizer-lag");
    // A "viewer" that accepts the connection and never reads: Rerun's client blocks once its
    // queues are full.
    let stuck = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!(
        "rerun+http://127.0.0.1:{}/proxy",
        stuck.local_addr().unwrap().port()
    );
    let accepting = std::thread::spawn(move || {
        let mut held = Vec::new();
        for conn in stuck.incoming().take(8).flatten() {
            held.push(conn);
        }
        held
    });
    // Frames at 100 Hz, so that Rerun's bounded buffers fill well within the run.
    let (ok, err, s) = run(
        &config(&dir, "lag", "[visualizer]\nrate_hz = 100"),
        &["--connect-viewer", &url],
    );
    assert!(ok, "{err}");
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["stale_tracked"], 0, "{s}");
    let rec = &s["recording"];
    assert_eq!(rec["target"], url, "{s}");
    assert!(rec["dropped"].as_u64().unwrap() > 0, "{s}");
    drop(accepting);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_streams_to_a_rerun_viewer_at_a_url() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("visualizer-connect");
    // The `rerun` of the same version as a server on a loopback port, saving what it receives.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let received = dir.join("received.rrd");
    // In a process group of its own: `rerun` is a Python launcher that starts the server as its
    // child, and both must go at the end.
    let mut viewer = Command::new(rerun())
        .args(["--bind", "127.0.0.1", "--port"])
        .arg(port.to_string())
        .arg("--save")
        .arg(&received)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .process_group(0)
        .spawn()
        .unwrap();
    let url = format!("rerun+http://127.0.0.1:{port}/proxy");
    let listening = (0..100).any(|_| {
        std::thread::sleep(std::time::Duration::from_millis(100));
        std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
    });
    assert!(listening, "the rerun server did not listen on {port}");
    let (ok, err, s) = run(&config(&dir, "connect", ""), &["--connect-viewer", &url]);
    std::thread::sleep(std::time::Duration::from_secs(2));
    kill_group(viewer.id());
    let _ = viewer.wait();
    assert!(ok, "{err}");
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["recording"]["target"], url, "{s}");
    assert_eq!(s["recording"]["dropped"], 0, "{s}");
    // What the viewer received is the run, as the summary says.
    read_back(&received, &s);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_plan_records_every_step_with_its_regions() {
    // Not beside a run: its CPU would starve the run's visualizer (at nice 10) at the start.
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("visualizer-plan");
    let rrd = dir.join("plan.rrd");
    let s = json_of(
        Command::new(env!("CARGO_BIN_EXE_icrflow"))
            .args(["plan", "config/paper_sphere.toml", "--json", "--out"])
            .arg(&dir)
            .arg("--rrd")
            .arg(&rrd)
            .current_dir(root()),
    );
    assert_eq!(s["completed"], true, "{s}");
    let r = read_rrd(&rrd, &s);
    // Every planned step once, in order, from the start (step 0).
    let steps: Vec<u64> = r["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as u64)
        .collect();
    let count = s["steps"].as_u64().unwrap();
    assert!(count > 50, "{s}");
    assert_eq!(steps, (0..count).collect::<Vec<_>>());
    let ids = r["recording_ids"].as_array().unwrap();
    assert!(
        ids.len() == 1 && ids[0].as_str().unwrap().starts_with("icrflow-plan-"),
        "{ids:?}"
    );
    // The run's entities, but latency: nothing ran.
    let entities = r["entities"].as_array().unwrap();
    for e in ENTITIES.iter().filter(|e| !e.contains("latency")) {
        assert!(entities.iter().any(|x| x == e), "{e} missing: {entities:?}");
    }
    assert!(
        !entities
            .iter()
            .any(|x| x.as_str().unwrap().contains("latency")),
        "{entities:?}"
    );
    // The paper's layout, without the latency row.
    let b = blueprint(&rrd);
    assert!(!view_names(&b).contains(&LATENCY.to_string()), "{b}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_bad_plan_recording_target_is_refused_before_planning() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("visualizer-plan-bad");
    let out = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["plan", "config/paper_sphere.toml", "--out"])
        .arg(&dir)
        .args(["--connect-viewer", "rerun+http://127.0.0.1/proxy"])
        .current_dir(root())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("--connect-viewer") && err.contains("no port"),
        "{err}"
    );
    assert!(!dir.join("trajectory.json").exists(), "nothing is planned");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_spawns_a_rerun_viewer_when_asked() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("visualizer-spawn");
    // `rerun` on the PATH: the test venv's rerun 0.36.3, through a script that adds
    // `--save FILE` so that what the spawned viewer receives is kept (this machine has no
    // display for its window; its server runs all the same).
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let received = dir.join("received.rrd");
    let pids = dir.join("pids");
    let script = bin.join("rerun");
    std::fs::write(
        &script,
        format!(
            "#!/bin/sh\necho $$ >> '{}'\nexec '{}' \"$@\" --save '{}'\n",
            pids.display(),
            rerun().display(),
            received.display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(&script, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = format!("rerun+http://127.0.0.1:{port}/proxy");
    let (ok, err, s) = run_with_path(
        &config(&dir, "spawn", &format!("[visualizer]\nurl = \"{url}\"")),
        &["--spawn-viewer"],
        Some(&bin),
    );
    std::thread::sleep(std::time::Duration::from_secs(2));
    // The viewer outlives the run (it is the user's window): stop it, its process group.
    let spawned = std::fs::read_to_string(&pids).unwrap_or_default();
    for pid in spawned.lines().filter_map(|p| p.parse().ok()) {
        kill_group(pid);
    }
    assert!(ok, "{err}");
    assert!(!spawned.is_empty(), "rerun was not started: {err}");
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(
        s["recording"]["target"],
        format!("spawned viewer ({url})"),
        "{s}"
    );
    read_back(&received, &s);
    let _ = std::fs::remove_dir_all(&dir);
}
