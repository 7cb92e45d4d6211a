//! The verbs speak with one voice: the same exit statuses (0 done, 1 error, 2 the answer is
//! no), the same alpha* for the same grasp (or each says which grasp it evaluates), clap's
//! suggestions for a mistyped verb or flag, Zenoh's errors in our words.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use common::{icrflow, scratch};

/// A grasp that is not force closure (the paper's own mu = 0.03) is an answer, not an error:
/// validate, analyze, plan and run all exit with status 2 and say why, and nothing is
/// written or started.
#[test]
fn a_grasp_without_force_closure_exits_2_from_every_verb() {
    let dir = scratch("voice-not-fc");
    let config = "config/paper_sphere_mu003.toml";
    let out = dir.join("plan");
    let summary = dir.join("summary.json");
    for args in [
        vec!["validate", config],
        vec!["analyze", config],
        vec!["analyze", config, "--json"],
        vec!["plan", config, "--out", out.to_str().unwrap()],
        vec![
            "run",
            config,
            "--no-visualizer",
            "--summary-json",
            summary.to_str().unwrap(),
        ],
    ] {
        let o = icrflow(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        let text = format!("{err}{}", String::from_utf8_lossy(&o.stdout));
        assert_eq!(o.status.code(), Some(2), "{args:?}: {text}");
        assert!(
            text.contains("not force closure") || text.contains("NOT force closure"),
            "{args:?}: {text}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(
        !out.join("trajectory.json").exists(),
        "plan wrote its files"
    );
    assert!(!summary.exists(), "run started");
    // The exit statuses are documented where a user looks.
    let help = icrflow(&["--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("Exit status: 0 done; 1 error") && help.contains("2 the work was done"),
        "{help}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn alpha_star(text: &str, after: &str) -> f64 {
    let rest = text
        .split(after)
        .nth(1)
        .unwrap_or_else(|| panic!("{after:?} not in {text}"));
    rest.split_whitespace()
        .next()
        .unwrap()
        .trim_end_matches(',')
        .parse()
        .unwrap_or_else(|_| panic!("no number after {after:?} in {text}"))
}

/// The ellipsoid's spatial grasp: validate and plan evaluate the contacts on the section in
/// the hand's plane, and agree; analyze evaluates them snapped to the mesh's facets (another
/// alpha*), and also gives the section's, which is theirs; each says which grasp it is.
#[test]
fn validate_analyze_and_plan_report_the_same_alpha_star_or_say_which_grasp() {
    let dir = scratch("voice-alpha");
    let config = "config/ellipsoid_spatial.toml";
    let v = icrflow(&["validate", config]);
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stderr));
    let v = String::from_utf8_lossy(&v.stdout).to_string();
    let validated = alpha_star(&v, "force closure, alpha* = ");
    assert!(
        v.contains("on the object's section in the hand's plane"),
        "{v}"
    );
    assert!(
        v.contains("analyze also snaps them to the nearest mesh facets"),
        "{v}"
    );

    let a = icrflow(&["analyze", config, "--json"]);
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let a: serde_json::Value = serde_json::from_slice(&a.stdout).unwrap();
    assert_eq!(a["contacts_on"], "facets", "{a}");
    let section = a["section_quality"].as_f64().unwrap();
    assert!(
        (section - validated).abs() <= 1e-6,
        "analyze's section grasp {section} vs validate's {validated}"
    );
    let text = icrflow(&["analyze", config]);
    let text = String::from_utf8_lossy(&text.stdout).to_string();
    assert!(
        text.contains("with the contacts on the nearest mesh facets"),
        "{text}"
    );
    assert!(
        (alpha_star(&text, "(validate, plan, run): alpha* = ") - validated).abs() <= 1e-6,
        "{text}"
    );
    // Spatial regions say where they lie, not only how many facets they have.
    assert!(
        text.contains("azimuth") && text.contains("elevation"),
        "{text}"
    );
    for c in a["contacts"].as_array().unwrap() {
        let e = &c["icr"]["extent"];
        let az = e["azimuth_deg"].as_array().unwrap();
        assert!(az[0].as_f64().unwrap() <= az[1].as_f64().unwrap(), "{c}");
        assert!(e["area"].as_f64().unwrap() > 0.0, "{c}");
    }

    let out = dir.join("plan");
    // With --progress-after 0 the plan's progress shows at once (not on a terminal: lines).
    let p = icrflow(&[
        "plan",
        config,
        "--out",
        out.to_str().unwrap(),
        "--progress-after",
        "0",
    ]);
    let err = String::from_utf8_lossy(&p.stderr);
    assert!(p.status.success(), "{err}");
    assert!(
        err.lines().any(|l| l.starts_with("planning   ")
            && l.contains(" % (")
            && l.contains(" of 360 deg), ")),
        "{err}"
    );
    let p = String::from_utf8_lossy(&p.stdout).to_string();
    assert!(
        (alpha_star(&p, "quality    alpha* = ") - validated).abs() <= 1e-6,
        "plan's start {p} vs validate's {validated}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Planar: one grasp for every verb, the same alpha*.
#[test]
fn a_planar_grasp_has_one_alpha_star_in_every_verb() {
    let dir = scratch("voice-planar");
    let config = "config/paper_sphere.toml";
    let v = icrflow(&["validate", config]);
    let validated = alpha_star(&String::from_utf8_lossy(&v.stdout), "alpha* = ");
    let a = icrflow(&["analyze", config, "--json"]);
    let a: serde_json::Value = serde_json::from_slice(&a.stdout).unwrap();
    assert_eq!(a["contacts_on"], "section");
    assert!(a["section_quality"].is_null(), "{a}");
    assert!(
        (a["quality"].as_f64().unwrap() - validated).abs() <= 1e-6,
        "{a}"
    );
    let out = dir.join("plan");
    let p = icrflow(&["plan", config, "--out", out.to_str().unwrap()]);
    let p = String::from_utf8_lossy(&p.stdout).to_string();
    assert!(
        (alpha_star(&p, "alpha* = ") - validated).abs() <= 1e-6,
        "{p}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A mistyped verb or flag gets clap's "did you mean", not a misleading tip.
#[test]
fn a_mistyped_verb_or_flag_gets_a_suggestion() {
    let o = icrflow(&["plna", "config/paper_sphere.toml"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("unrecognized subcommand 'plna'") && err.contains("similar subcommand"),
        "{err}"
    );
    assert!(err.contains("'plan'"), "{err}");
    for (flag, similar) in [("--spawn", "--spawn-viewer"), ("--rdd", "--rrd")] {
        let o = icrflow(&["run", "config/paper_sphere.toml", flag]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains("similar argument") && err.contains(similar),
            "{flag}: {err}"
        );
        assert!(!err.contains(&format!("-- {flag}")), "{flag}: {err}");
    }
}

/// Zenoh's errors reach the user in our words, naming the endpoint and what is wrong with it,
/// without Zenoh's internals (its error type's debug form, a path into the cargo registry).
#[test]
fn a_bad_zenoh_endpoint_is_named_in_our_words() {
    for (endpoint, says) in [
        ("localhost:7447", "is not an endpoint like"),
        ("udp/127.0.0.1:7447", "only tcp endpoints are built in"),
        ("tcp/127.0.0.1", "expected tcp/HOST:PORT"),
        (
            "tcp/127.0.0.1:7447#=x",
            "Zenoh refused the setting connect/endpoints",
        ),
    ] {
        let o = icrflow(&["monitor", "--connect", endpoint, "--seconds", "1"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{endpoint}: {err}");
        assert!(
            err.contains(says) && err.contains(endpoint),
            "{endpoint}: {err}"
        );
        for raw in ["Json5Err", "Message {", ".cargo/registry", "panicked"] {
            assert!(!err.contains(raw), "{endpoint}: {err}");
        }
    }
}
