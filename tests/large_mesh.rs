//! Large meshes (issue #18): `validate`, `analyze` and `plan` warn of a mesh file above
//! the size guidance as soon as its size is known, and show the progress of loading it and
//! building the grasp problem (`--progress-after`, checked like any flag).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use std::path::{Path, PathBuf};

use common::{icrflow, root, scratch};
use icrflow_grasp::math::Vec3;
use icrflow_grasp::object::Object;

/// The stages every mesh file goes through, as the progress lines name them.
const STAGES: [&str; 7] = [
    "reading the mesh",
    "welding vertices",
    "checking faces and edges",
    "facets and their neighbours",
    "cutting the section",
    "object and contact wrenches",
    "support tree over the object wrenches",
];

/// `config/ellipsoid_spatial.toml` with its mesh replaced by `mesh`, written as `dir/NAME`.
fn config_with_mesh(dir: &Path, name: &str, mesh: &Path) -> PathBuf {
    let text = std::fs::read_to_string(root().join("config/ellipsoid_spatial.toml")).unwrap();
    let text = text.replace(
        "path = \"meshes/ellipsoid_55x45x40mm.stl\"",
        &format!("path = {:?}", mesh.display().to_string()),
    );
    assert!(text.contains(&mesh.display().to_string()), "{text}");
    let config = dir.join(name);
    std::fs::write(&config, text).unwrap();
    config
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_mesh_above_the_size_guidance_is_warned_of_and_its_loading_shown() {
    let dir = scratch("large-mesh");
    // The ellipsoid of config/ellipsoid_spatial.toml, 512 x 490 segments: 2 * 512 * 489 =
    // 500736 triangles in the STL file, just above the guidance (500000).
    let mesh = dir.join("ellipsoid_500k.stl");
    Object::ellipsoid(Vec3::new(0.055, 0.045, 0.040), 512, 490)
        .unwrap()
        .write_stl(&mesh)
        .unwrap();
    let config = config_with_mesh(&dir, "large.toml", &mesh);
    let config = config.to_str().unwrap();

    let o = icrflow(&["validate", config, "--progress-after", "0"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("is valid"),
        "{err}"
    );
    // The warning comes first, as soon as the binary STL's header gives the count, and says
    // what it costs and what to do.
    let warning = "warning    the mesh has 500736 faces (more than 500000): expect ~";
    assert!(
        err.lines().next().unwrap_or_default().starts_with(warning),
        "{err}"
    );
    assert!(
        err.contains(" s to load it and build the grasp problem") && err.contains("decimate it"),
        "{err}"
    );
    // Then one line per stage as it ends, in order, with what it counted.
    let mut at = 0;
    for stage in STAGES {
        let line = format!("progress   {stage}: ");
        let found = err[at..]
            .find(&line)
            .unwrap_or_else(|| panic!("{line:?} in {err}"));
        at += found + line.len();
    }
    assert!(
        err.contains("progress   reading the mesh: 500736 faces in "),
        "{err}"
    );
    assert!(
        err.contains(
            "progress   support tree over the object wrenches: 500736 object wrenches in "
        ),
        "{err}"
    );

    // With a delay no validation reaches, the warning alone.
    let o = icrflow(&["validate", config, "--progress-after", "3600"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with(warning), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_small_mesh_gets_no_warning_and_every_verb_shows_its_loading_when_asked() {
    let config = "config/ellipsoid_spatial.toml";
    for verb in [
        &["validate", config][..],
        &["analyze", config],
        &["plan", config, "--json"],
    ] {
        let dir = scratch("small-mesh-plan");
        let out = dir.join("out");
        let mut args = verb.to_vec();
        if verb[0] == "plan" {
            args.extend(["--out", out.to_str().unwrap()]);
        }
        let mut asked = args.clone();
        asked.extend(["--progress-after", "0"]);
        let o = icrflow(&asked);
        let err = stderr(&o);
        assert!(o.status.success(), "{verb:?}: {err}");
        assert!(!err.contains("warning"), "{verb:?}: {err}");
        // 5040 triangles, welded to 2522 vertices.
        assert!(
            err.contains("progress   reading the mesh: 5040 faces in "),
            "{verb:?}: {err}"
        );
        for stage in STAGES {
            assert!(
                err.contains(&format!("progress   {stage}: ")),
                "{verb:?}: {stage}: {err}"
            );
        }
        // Not asked (a delay nothing here reaches): nothing on stderr.
        args.extend(["--progress-after", "3600"]);
        let o = icrflow(&args);
        assert!(o.status.success(), "{verb:?}: {}", stderr(&o));
        assert_eq!(stderr(&o), "", "{verb:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn a_bad_progress_delay_is_refused_naming_the_flag() {
    for (value, why) in [
        ("-1", "outside 0 to 3600 s"),
        ("3601", "outside 0 to 3600 s"),
        ("nan", "outside 0 to 3600 s"),
        ("inf", "outside 0 to 3600 s"),
        ("soon", "is not a number of seconds"),
    ] {
        let arg = format!("--progress-after={value}");
        let o = icrflow(&["validate", "config/ellipsoid_spatial.toml", &arg]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{value}: {err}");
        assert!(err.contains("--progress-after"), "{value}: {err}");
        assert!(err.contains(why), "{value}: {err}");
        assert!(!err.contains("panicked"), "{value}: {err}");
    }
}

#[test]
fn the_progress_delay_is_offered_by_the_verbs_it_acts_on_only() {
    // Offered (and taken) by validate, analyze and plan; not by run, monitor, render.
    for verb in ["validate", "analyze", "plan", "run", "monitor", "render"] {
        let o = icrflow(&[verb, "--help"]);
        let help = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{verb}: {}", stderr(&o));
        let acts = matches!(verb, "validate" | "analyze" | "plan");
        assert_eq!(help.contains("--progress-after"), acts, "{verb}: {help}");
    }
    let o = icrflow(&["render", "x.rrd", "--out", "x.png", "--progress-after", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("unexpected argument '--progress-after'"),
        "{}",
        stderr(&o)
    );
    // Before the verb, as when the flag was global: still taken by the verbs it acts on,
    // refused (a usage error) before the others.
    let config = "config/ellipsoid_spatial.toml";
    let o = icrflow(&["--progress-after", "0", "validate", config]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("progress   reading the mesh: "),
        "{}",
        stderr(&o)
    );
    let o = icrflow(&["--progress-after", "0", "monitor", "--seconds", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--progress-after acts on validate, analyze and plan only"),
        "{}",
        stderr(&o)
    );
}
