//! Remote monitoring over Zenoh (issue #5), end to end: a real `icrflow run` with its bridge
//! listening on a loopback port of its own, read by an external Python `eclipse-zenoh` client
//! (tests/zenoh_client.py) and by `icrflow monitor`.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use std::process::{Command, Stdio};
use std::time::Duration;

use common::{python, root, scratch};

/// One pipeline at a time (each is six processes on this machine's cores).
static PIPELINE: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The monitoring topics the bridge publishes by default.
const TOPICS: [&str; 6] = icrflow_scenario::DEFAULT_MONITOR;

/// What [`watched_run`] saw.
struct Watched {
    /// The run's stderr.
    run_err: String,
    /// The monitoring client's report.
    report: serde_json::Value,
    /// The monitor's last line.
    last: String,
    /// The replies the asking client got.
    replies: u64,
    /// The report of the client subscribing with [`KEY_EXPRS`].
    keys: serde_json::Value,
}

/// Key expressions a generic Zenoh client may subscribe with to read rig `ztest`: wider than
/// the rig's, the rig's, and narrower.
const KEY_EXPRS: [&str; 5] = [
    "icrflow/**",
    "icrflow/ztest/**",
    "**",
    "icrflow/*/grasp_state",
    "icrflow/ztest/*",
];

/// The paper scenario's config with `extra` appended, written as `dir/name.toml`.
fn paper_config(dir: &std::path::Path, name: &str, extra: &str) -> std::path::PathBuf {
    let good = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    let config = dir.join(format!("{name}.toml"));
    std::fs::write(&config, format!("{good}\n{extra}\n")).unwrap();
    config
}

/// `icrflow run CONFIG --summary-json` beside it, its stderr piped; and the summary's path.
fn spawn_run(config: &std::path::Path) -> (std::process::Child, std::path::PathBuf) {
    let summary = config.with_extension("json");
    let run = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["run", config.to_str().unwrap(), "--summary-json"])
        .arg(&summary)
        .current_dir(root())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (run, summary)
}

/// A run's summary.
fn read_summary(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// A loopback TCP port nobody listens on now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A run of the paper scenario with its bridge on a loopback port of its own (`extra` appended
/// to its `[zenoh]` section), the Python client and `icrflow monitor` reading it meanwhile.
/// Meanwhile a second client answers queries on the hand command key and a third asks it,
/// and a fourth subscribes with the key expressions of [`KEY_EXPRS`], one session each, then
/// puts marked messages from another session.
fn watched_run(name: &str, extra: &str) -> Watched {
    let dir = scratch(name);
    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let rig = "ztest";
    let config = paper_config(
        &dir,
        "zenoh",
        &format!("[pipeline]\nrig = \"{rig}\"\n\n[zenoh]\nlisten = [\"{endpoint}\"]\n{extra}"),
    );
    let (run, summary) = spawn_run(&config);
    // The client and the monitor connect while the run goes on (it takes ~15 s).
    std::thread::sleep(Duration::from_secs(2));
    let monitor = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args([
            "monitor",
            "--connect",
            &endpoint,
            "--rig",
            rig,
            "--seconds",
            "4",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let keys = Command::new(python())
        .arg(root().join("tests/zenoh_client.py"))
        .args(["--keys", &endpoint, rig, "8"])
        .args(KEY_EXPRS)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut answering = Command::new(python())
        .arg(root().join("tests/zenoh_client.py"))
        .args(["--answer", &endpoint, rig, "60"])
        .spawn()
        .unwrap();
    let client = Command::new(python())
        .arg(root().join("tests/zenoh_client.py"))
        .args([&endpoint, rig, "20"])
        .args(TOPICS)
        .output()
        .unwrap();
    let asked = Command::new(python())
        .arg(root().join("tests/zenoh_client.py"))
        .args(["--ask", &endpoint, rig])
        .output()
        .unwrap();
    let asked: serde_json::Value =
        serde_json::from_slice(&asked.stdout).unwrap_or_else(|_| serde_json::json!({}));
    let replies = asked["replies"]
        .as_u64()
        .expect("the asking client's report");
    let _ = answering.kill();
    let _ = answering.wait();
    let keys = keys.wait_with_output().unwrap();
    let keys_out = String::from_utf8_lossy(&keys.stdout);
    assert!(
        keys.status.success(),
        "key expression client: {keys_out}\n{}",
        String::from_utf8_lossy(&keys.stderr)
    );
    let keys: serde_json::Value = serde_json::from_str(keys_out.trim()).unwrap();
    let monitor = monitor.wait_with_output().unwrap();
    let run = run.wait_with_output().unwrap();
    let run_err = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(run.status.success(), "run failed: {run_err}");
    let s = read_summary(&summary);
    assert_eq!(s["completed"], true, "{s}");

    // The external client received and decoded every monitoring topic.
    let report = String::from_utf8_lossy(&client.stdout);
    assert!(
        client.status.success(),
        "client: {report}\n{}",
        String::from_utf8_lossy(&client.stderr)
    );
    let report: serde_json::Value = serde_json::from_str(report.trim()).unwrap();
    for t in TOPICS {
        let key = format!("icrflow/{rig}/{t}");
        assert!(
            report["decoded"][&key].as_u64().unwrap_or(0) >= 20,
            "{key}: {report}"
        );
    }
    assert_eq!(report["errors"], serde_json::json!([]), "{report}");

    // The monitor, not on a terminal, printed plain lines of the live state.
    let text = String::from_utf8_lossy(&monitor.stdout);
    let err = String::from_utf8_lossy(&monitor.stderr);
    assert!(monitor.status.success(), "monitor: {err}");
    let last = last_state(&text);
    assert!(text.lines().count() >= 2, "monitor printed: {text}\n{err}");
    assert_short(&text);
    let _ = std::fs::remove_dir_all(&dir);
    Watched {
        run_err,
        report,
        last,
        replies,
        keys,
    }
}

/// The last state a monitor printed as plain lines: the lines of its last second (each begins
/// with its time).
fn last_state(text: &str) -> String {
    let time = text
        .lines()
        .last()
        .and_then(|l| l.split(' ').next())
        .unwrap_or_default();
    text.lines()
        .filter(|l| l.starts_with(&format!("{time} ")))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every plain line of a monitor is at most 100 characters long.
fn assert_short(text: &str) {
    for l in text.lines() {
        assert!(
            l.chars().count() <= 100,
            "{} characters: {l}",
            l.chars().count()
        );
    }
}

/// Every key expression of [`KEY_EXPRS`] received the rig's monitoring topics it matches, at
/// least 5 messages each; read-only, nothing else (no key but those topics', none of the
/// marked puts of the other session).
fn assert_every_key_expression_reads(keys: &serde_json::Value, read_only: bool) {
    assert_eq!(keys["complete"], true, "{keys:#}");
    for expr in KEY_EXPRS {
        let got = &keys["keys"][expr];
        let expected: Vec<&str> = if expr == "icrflow/*/grasp_state" {
            vec!["grasp_state"]
        } else {
            TOPICS.to_vec()
        };
        for t in &expected {
            let n = got["topics"][format!("icrflow/ztest/{t}")]
                .as_u64()
                .unwrap_or(0);
            assert!(n >= 5, "{expr}: {n} messages of {t}: {keys:#}");
        }
        if read_only {
            let topics = got["topics"].as_object().expect("the topics received");
            for key in topics.keys() {
                let topic = key.strip_prefix("icrflow/ztest/").unwrap_or(key);
                assert!(expected.contains(&topic), "{expr} received {key}: {keys:#}");
            }
            assert_eq!(got["foreign"], 0, "{expr} received a remote put: {keys:#}");
        }
    }
}

#[test]
fn a_zenoh_client_reads_every_monitoring_topic_of_a_run_and_cannot_write() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let Watched {
        run_err,
        report,
        last,
        replies,
        keys,
    } = watched_run("zenoh", "");
    for part in [
        "phase ",
        "rotation ",
        "deg",
        "quality   alpha*",
        "contacts ",
        "nodes ",
    ] {
        assert!(last.contains(part), "{part:?} missing in {last:?}");
    }
    assert!(
        last.contains("plant running") || last.contains("plant degraded"),
        "{last}"
    );
    // Every part of the view has data ("(no plan step yet)" and the like are gone).
    assert!(!last.contains(" yet)"), "{last}");
    // The client's puts on the hand command key were sent, and the access control dropped
    // them: the bridge, the only way from Zenoh to the local bus, never saw one (it logs
    // every remote message it gets; the next test shows it does when writes are allowed).
    assert_eq!(report["put"]["icrflow/ztest/hand_command"], 3, "{report}");
    assert!(!run_err.contains("remote message"), "{run_err}");
    // A remote queryable on the hand command key answers nobody through the pipeline.
    assert_eq!(
        replies, 0,
        "a remote queryable answered for the hand command"
    );
    // A client reads the rig with any key expression, `icrflow/**` and `**` included (the
    // access control once dropped every subscriber wider than `icrflow/ztest/**`), and
    // another client's puts reach neither it nor the bridge.
    assert_every_key_expression_reads(&keys, true);
    assert_eq!(keys["put"]["icrflow/ztest/hand_command"], 5, "{keys}");
}

#[test]
fn without_access_control_remote_writes_reach_the_bridge_which_ignores_them_and_says_why() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let Watched {
        run_err,
        report,
        replies,
        keys,
        ..
    } = watched_run("zenoh-open", "read_only = false");
    // Without access control the pipeline's session passes one client's puts on to the
    // others: the control case of the read-only test's "no remote put reaches a subscriber".
    assert_every_key_expression_reads(&keys, false);
    for expr in ["icrflow/**", "**", "icrflow/ztest/**", "icrflow/ztest/*"] {
        assert!(
            keys["keys"][expr]["foreign"].as_u64().unwrap_or(0) > 0,
            "{expr}: {keys:#}"
        );
    }
    // Without access control the pipeline's session routes a query to a remote queryable.
    assert_eq!(
        replies, 1,
        "the control case: the query should have been answered"
    );
    assert_eq!(report["put"]["icrflow/ztest/hand_command"], 3, "{report}");
    let key = "icrflow/ztest/hand_command";
    for why in [
        "the bridge takes no input on it",
        "malformed monitoring JSON",
        "monitoring schema 99, expected 1",
    ] {
        assert!(
            run_err.contains(&format!(
                "icrflow-bridge: ignored a remote message on {key}: {why}"
            )),
            "{why}: {run_err}"
        );
    }
}

#[test]
fn a_run_goes_on_when_its_bridge_cannot_listen() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-taken");
    // Someone else holds the bridge's port.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let endpoint = format!("tcp/{}", taken.local_addr().unwrap());
    let config = paper_config(
        &dir,
        "taken",
        &format!("[zenoh]\nlisten = [\"{endpoint}\"]"),
    );
    let (run, summary) = spawn_run(&config);
    let run = run.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    let s = read_summary(&summary);
    assert_eq!(s["completed"], true, "{s}");
    // The bridge said why it could not start, naming its endpoint, and the run went on.
    assert!(
        err.contains("icrflow-bridge: error: cannot open the Zenoh session")
            && err.contains(&endpoint),
        "{err}"
    );
    assert!(err.contains("node bridge exited"), "{err}");
    drop(taken);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_remote_peer_that_stops_reading_does_not_stall_the_run() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-stall");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let config = paper_config(
        &dir,
        "stall",
        &format!("[zenoh]\nlisten = [\"{endpoint}\"]"),
    );
    let (run, summary) = spawn_run(&config);
    std::thread::sleep(Duration::from_secs(1));
    // A peer that takes the first sample and then never reads again, for longer than the run.
    let mut stalled = Command::new(python())
        .arg(root().join("tests/zenoh_client.py"))
        .args(["--stall", &endpoint, "sim", "120"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let run = run.wait_with_output().unwrap();
    // The run is over and the peer is still stuck in its callback.
    let still_stuck = stalled.try_wait().unwrap().is_none();
    let _ = stalled.kill();
    let stalled = stalled.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    let s = read_summary(&summary);
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["stale_tracked"], 0, "{s}");
    // The run finished while the peer was stuck, and the bridge neither died nor was
    // restarted on its account.
    assert!(still_stuck, "the stalled peer ended before the run");
    let report = String::from_utf8_lossy(&stalled.stdout);
    assert!(
        report.contains("\"stalled\": true"),
        "the peer never got a sample: {report}"
    );
    assert_eq!(s["restarts"], 0, "{s}");
    assert!(!err.contains("node bridge exited"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn with_a_users_file_only_peers_that_log_in_read_the_run() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-users");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let password = format!("pw-{}", std::process::id());
    std::fs::write(dir.join("users.txt"), format!("monitor:{password}\n")).unwrap();
    let config = paper_config(
        &dir,
        "users",
        &format!("[zenoh]\nlisten = [\"{endpoint}\"]\nusers_file = \"users.txt\""),
    );
    let (run, _) = spawn_run(&config);
    std::thread::sleep(Duration::from_secs(2));
    // All while the run goes on (~13 s): the clients without the right password at once, in
    // parallel, then the one with it and the monitors.
    let client = |login: Option<(&str, &str)>, seconds: &str| {
        let mut c = Command::new(python());
        c.arg(root().join("tests/zenoh_client.py"))
            .args([&endpoint, "sim", seconds])
            .args(["grasp_state", "hand_command"])
            .stdout(Stdio::piped());
        if let Some((user, password)) = login {
            c.env("ZENOH_USER", user).env("ZENOH_PASSWORD", password);
        }
        c.spawn().unwrap()
    };
    let result = |c: std::process::Child| {
        let o = c.wait_with_output().unwrap();
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        (o.status.success(), text)
    };
    let anonymous = client(None, "5");
    let wrong = client(Some(("monitor", "not-the-password")), "5");
    let (user_ok, user) = result(client(Some(("monitor", &password)), "20"));
    let monitor = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["monitor", "--connect", &endpoint, "--user", "monitor"])
        .args(["--seconds", "2"])
        .env("ICRFLOW_ZENOH_PASSWORD", &password)
        .output()
        .unwrap();
    // On a terminal (util-linux `script` gives it one) the view is redrawn in place.
    let on_terminal = Command::new("script")
        .arg("-qec")
        .arg(format!(
            "{} monitor --connect {endpoint} --user monitor --seconds 2",
            env!("CARGO_BIN_EXE_icrflow")
        ))
        .arg("/dev/null")
        .env("ICRFLOW_ZENOH_PASSWORD", &password)
        .output()
        .unwrap();
    let (anonymous_ok, anonymous) = result(anonymous);
    let (wrong_ok, wrong) = result(wrong);
    let run = run.wait_with_output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // Without the password, or with a wrong one, nothing is read; with it, everything.
    assert!(
        !anonymous_ok && !anonymous.contains("icrflow/sim/"),
        "{anonymous}"
    );
    assert!(!wrong_ok && !wrong.contains("icrflow/sim/"), "{wrong}");
    assert!(user_ok, "{user}");
    // The monitors showed live data: a rotation in degrees, not "(no grasp state yet)".
    let live = |text: &str| {
        text.split("rotation  ")
            .skip(1)
            .any(|rest| rest.starts_with(|c: char| c.is_ascii_digit()))
    };
    let text = String::from_utf8_lossy(&monitor.stdout);
    assert!(
        monitor.status.success() && live(&text),
        "{text}\n{}",
        String::from_utf8_lossy(&monitor.stderr)
    );
    let screen = String::from_utf8_lossy(&on_terminal.stdout);
    assert!(on_terminal.status.success(), "{screen}");
    assert!(
        screen.matches("\x1b[H").count() >= 5 && live(&screen),
        "not redrawn in place with live data: {screen:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_killed_bridge_is_restarted_and_the_monitor_reconnects() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-kill");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let config = paper_config(&dir, "kill", &format!("[zenoh]\nlisten = [\"{endpoint}\"]"));
    let (run, summary) = spawn_run(&config);
    std::thread::sleep(Duration::from_secs(2));
    let monitor = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["monitor", "--connect", &endpoint, "--seconds", "10"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(3));
    // The bridge of this run (the only one whose command line names this config).
    let bridge = std::fs::read_dir("/proc")
        .unwrap()
        .flatten()
        .find_map(|e| {
            let pid: u32 = e.file_name().to_string_lossy().parse().ok()?;
            let cmd = std::fs::read(e.path().join("cmdline")).ok()?;
            let cmd = String::from_utf8_lossy(&cmd);
            (cmd.contains("icrflow-bridge") && cmd.contains(config.to_str().unwrap()))
                .then_some(pid)
        })
        .expect("the bridge is running");
    assert!(
        Command::new("kill")
            .args(["-9", &bridge.to_string()])
            .status()
            .unwrap()
            .success()
    );
    let monitor = monitor.wait_with_output().unwrap();
    let run = run.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains("node bridge exited (killed by SIGKILL)"),
        "{err}"
    );
    assert!(err.contains("run: restarted bridge"), "{err}");
    let s = read_summary(&summary);
    assert_eq!(s["completed"], true, "{s}");
    // The rotation the monitor shows went on growing after the kill: it reconnected to the
    // restarted bridge (a monitor left without data would repeat the last state).
    let text = String::from_utf8_lossy(&monitor.stdout);
    assert!(text.lines().count() >= 8, "{text}");
    let rotations: Vec<f64> = text
        .lines()
        .filter_map(|l| {
            let r = l.split("rotation").nth(1)?;
            r.split_whitespace().next()?.parse().ok()
        })
        .collect();
    let (early, late) = (rotations[2], *rotations.last().unwrap());
    assert!(
        late > early + 20.0,
        "no progress seen after the kill: {text}"
    );
    // And it shows the bridge's restart (a new process of the node), not "running" throughout.
    assert!(last_state(&text).contains("(restarted 1x"), "{text}");
    assert_short(&text);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `icrflow monitor` started before any run waits for one (saying so) and then shows it; one
/// given another rig than the run's warns, naming the rig that does publish there, and exits
/// with status 2 (nothing came for its rig).
#[test]
fn the_monitor_waits_for_a_run_and_warns_of_a_wrong_rig() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-wait");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let monitor = |rig: &str, seconds: &str| {
        Command::new(env!("CARGO_BIN_EXE_icrflow"))
            .args(["monitor", "--connect", &endpoint, "--rig", rig])
            .args(["--seconds", seconds])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    // Nothing listens at the endpoint yet.
    let early = monitor("sim", "14");
    std::thread::sleep(Duration::from_secs(2));
    let config = paper_config(&dir, "wait", &format!("[zenoh]\nlisten = [\"{endpoint}\"]"));
    let (run, summary) = spawn_run(&config);
    std::thread::sleep(Duration::from_secs(2));
    let wrong = monitor("not-this-rig", "6");
    let early = early.wait_with_output().unwrap();
    let wrong = wrong.wait_with_output().unwrap();
    let run = run.wait_with_output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(read_summary(&summary)["completed"], true);
    let err = String::from_utf8_lossy(&early.stderr);
    let text = String::from_utf8_lossy(&early.stdout);
    assert_eq!(early.status.code(), Some(0), "{err}\n{text}");
    assert!(
        err.contains(&format!("monitor: no run answers at {endpoint} yet"))
            && err.contains("waiting for one"),
        "{err}"
    );
    assert!(
        err.contains(&format!("monitor: connected to {endpoint} after")),
        "{err}"
    );
    // It showed the run once it came: a rotation, and the contacts as angles.
    assert!(
        text.split("rotation  ")
            .skip(1)
            .any(|rest| rest.starts_with(|c: char| c.is_ascii_digit())),
        "{text}"
    );
    assert!(
        text.contains("finger 1 at ") && text.contains(" deg"),
        "{text}"
    );
    assert!(!text.contains("1@"), "{text}");
    let err = String::from_utf8_lossy(&wrong.stderr);
    assert_eq!(wrong.status.code(), Some(2), "{err}");
    assert!(
        err.contains("nothing has arrived for rig \"not-this-rig\"")
            && err.contains("rig(s) sim publish at")
            && err.contains("--rig sim?"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `icrflow monitor` says when the run it watches has ended (every node it saw gone silent),
/// in its view and once on stderr, instead of each node as SILENT; its plain lines are short.
#[test]
fn the_monitor_says_when_the_run_ended() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-ended");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let config = paper_config(
        &dir,
        "ended",
        &format!("[zenoh]\nlisten = [\"{endpoint}\"]"),
    );
    // A short run: a sixth of a turn.
    let text = std::fs::read_to_string(&config).unwrap();
    std::fs::write(
        &config,
        text.replace("rotation_deg = 360.0", "rotation_deg = 60.0"),
    )
    .unwrap();
    let summary = config.with_extension("json");
    let run = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args([
            "run",
            config.to_str().unwrap(),
            "--no-visualizer",
            "--summary-json",
        ])
        .arg(&summary)
        .current_dir(root())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(1));
    let monitor = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["monitor", "--connect", &endpoint, "--seconds", "12"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let run = run.wait_with_output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(read_summary(&summary)["completed"], true);
    let monitor = monitor.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&monitor.stdout);
    let err = String::from_utf8_lossy(&monitor.stderr);
    assert!(monitor.status.success(), "{err}\n{text}");
    // It saw the run, then its end.
    assert!(text.contains("plant running"), "{text}");
    assert_eq!(
        err.matches("monitor: the run has ended").count(),
        1,
        "{err}"
    );
    let last = last_state(&text);
    assert!(
        last.contains("RUN ENDED: no node has reported for"),
        "{last}"
    );
    assert!(
        last.contains("nodes     ended: ") && !last.contains("SILENT"),
        "{last}"
    );
    assert_short(&text);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A split run whose other host never comes says on its status line which input it waits for,
/// and from where, once its planner has planned (not the planner's last "planning: N %").
#[test]
fn a_split_run_says_which_input_from_the_other_host_it_waits_for() {
    use std::io::BufRead as _;
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-alone");
    let (listen, connect) = (
        format!("tcp/127.0.0.1:{}", free_port()),
        format!("tcp/127.0.0.1:{}", free_port()),
    );
    // The workstation's half of config/split_workstation.toml, the robot's host absent.
    let config = paper_config(
        &dir,
        "alone",
        &format!(
            "[pipeline]\nnodes = [\"wrench\", \"planner\"]\n\n[zenoh]\nlisten = [\"{listen}\"]\nconnect = [\"{connect}\"]"
        ),
    );
    let mut run = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["run", config.to_str().unwrap(), "--no-visualizer"])
        .current_dir(root())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let want = format!(
        "run: waiting for grasp_state from the other host (Zenoh, connecting to {connect}, listening on {listen}), "
    );
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = run.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut said = String::new();
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            said.push_str(&line);
            said.push('\n');
            let _ = tx.send(line);
        }
        said
    });
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let mut found = false;
    while let Some(rest) = deadline.checked_duration_since(std::time::Instant::now()) {
        match rx.recv_timeout(rest) {
            Ok(line) if line.starts_with(&want) => {
                found = true;
                break;
            }
            Ok(_) => {}
            Err(_) => break,
        }
    }
    let interrupted = Command::new("kill")
        .args(["-INT", &run.id().to_string()])
        .status()
        .unwrap();
    assert!(interrupted.success());
    let _ = run.wait();
    let said = reader.join().unwrap();
    assert!(found, "never said {want:?}:\n{said}");
    let _ = std::fs::remove_dir_all(&dir);
}
