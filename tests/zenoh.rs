//! Remote monitoring over Zenoh (issue #5), end to end: a real `icrflow run` with its bridge
//! listening on a loopback port of its own, read by an external Python `eclipse-zenoh` client
//! (tests/zenoh_client.py) and by `icrflow monitor`.

mod common;

use std::process::{Command, Stdio};
use std::time::Duration;

use common::{root, scratch};

/// One pipeline at a time (each is six processes on this machine's cores).
static PIPELINE: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The monitoring topics the bridge publishes by default.
const TOPICS: [&str; 6] = [
    "joint_state",
    "grasp_state",
    "wrench_space",
    "plan_step",
    "hand_command",
    "node_health",
];

/// The Python interpreter of the test venv (scripts/setup-python.sh installs eclipse-zenoh).
fn python() -> String {
    if let Ok(py) = std::env::var("ICRFLOW_PYTHON") {
        return py;
    }
    let out = Command::new(root().join("scripts/setup-python.sh"))
        .output()
        .expect("running scripts/setup-python.sh");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .last()
        .unwrap()
        .trim()
        .to_string()
}

/// A loopback TCP port nobody listens on now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

#[test]
fn a_zenoh_client_reads_every_monitoring_topic_of_a_run() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh");
    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let rig = "ztest";
    let good = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    let config = dir.join("zenoh.toml");
    std::fs::write(
        &config,
        format!("{good}\n[pipeline]\nrig = \"{rig}\"\n\n[zenoh]\nlisten = [\"{endpoint}\"]\n"),
    )
    .unwrap();
    let summary = dir.join("summary.json");
    let run = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["run", config.to_str().unwrap(), "--summary-json"])
        .arg(&summary)
        .current_dir(root())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
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
    let client = Command::new(python())
        .arg(root().join("tests/zenoh_client.py"))
        .args([&endpoint, rig, "20"])
        .args(TOPICS)
        .output()
        .unwrap();
    let monitor = monitor.wait_with_output().unwrap();
    let run = run.wait_with_output().unwrap();
    let run_err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "run failed: {run_err}");

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
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines.len() >= 2, "monitor printed: {text}\n{err}");
    let last = lines.last().unwrap();
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
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_goes_on_when_its_bridge_cannot_listen() {
    let _one = PIPELINE.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch("zenoh-taken");
    // Someone else holds the bridge's port.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let endpoint = format!("tcp/{}", taken.local_addr().unwrap());
    let good = std::fs::read_to_string(root().join("config/paper_sphere.toml")).unwrap();
    let config = dir.join("taken.toml");
    std::fs::write(
        &config,
        format!("{good}\n[zenoh]\nlisten = [\"{endpoint}\"]\n"),
    )
    .unwrap();
    let summary = dir.join("summary.json");
    let run = Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(["run", config.to_str().unwrap(), "--summary-json"])
        .arg(&summary)
        .current_dir(root())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
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
