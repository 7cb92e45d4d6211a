//! Cross-implementation check against `bench/reference_qhull.py` (numpy + scipy.spatial,
//! i.e. Qhull, written from DESIGN.md independently of this crate): on shared random cases,
//! force closure, alpha*, epsilon and every ICR must agree. The Python side is installed by
//! `scripts/setup-python.sh` (a venv outside the repo) unless `ICRFLOW_PYTHON` names an
//! interpreter that has it.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::Rng;
use common::reference::{Case, cases_json};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::wrench::{ContactModel, Space};

/// The package's directory, as cargo gives it when running the test (a test binary cached from
/// another checkout of the same commit would carry that checkout's compile-time path).
fn manifest_dir() -> std::ffi::OsString {
    std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into())
}
fn repo_root() -> PathBuf {
    Path::new(&manifest_dir()).parent().unwrap().to_path_buf()
}

fn python() -> String {
    if let Ok(py) = std::env::var("ICRFLOW_PYTHON") {
        return py;
    }
    let out = Command::new(repo_root().join("scripts/setup-python.sh"))
        .output()
        .expect("running scripts/setup-python.sh");
    assert!(
        out.status.success(),
        "scripts/setup-python.sh failed:\n{}",
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

struct Expect {
    force_closure: bool,
    quality: Real,
    epsilon: Real,
    regions: Option<Vec<Vec<u32>>>,
}

#[test]
fn rust_and_python_qhull_agree() {
    // Leaked so that the cases can borrow them from the closure below; the test is short.
    let sphere: &'static Object = Box::leak(Box::new(Object::sphere(0.0475, 36, 36).unwrap()));
    let paper: &'static Object = Box::leak(Box::new(Object::sphere(0.0475, 72, 72).unwrap()));
    let ellipsoid: &'static Object = Box::leak(Box::new(common::ellipsoid_mesh(30)));
    let cuboid: &'static Object = Box::leak(Box::new(
        Object::cuboid(Vec3::new(0.04, 0.03, 0.025), 5).unwrap(),
    ));
    let mut rng = Rng(42);
    let mut cases = Vec::new();
    let mut expected = Vec::new();
    let mut add = |id: String,
                   object: &'static Object,
                   space: Space,
                   mu: Real,
                   contacts: Vec<usize>,
                   rng: &mut Rng| {
        let p = common::problem(object, space, mu, 8);
        let e = p.evaluate(&contacts).unwrap();
        // Margins: half the quality (regions of useful size), or an arbitrary one when the
        // grasp is not force closure (both sides must refuse).
        let alpha = if e.force_closure() {
            e.quality * rng.uniform(0.3, 0.9)
        } else {
            0.05
        };
        let regions = p
            .icrs(&contacts, &e, alpha)
            .ok()
            .map(|r| r.into_iter().map(|r| r.members).collect());
        expected.push(Expect {
            force_closure: e.force_closure(),
            quality: e.quality,
            epsilon: e.epsilon,
            regions,
        });
        cases.push(Case {
            id,
            object,
            candidates: common::candidates(object, space),
            space,
            model: ContactModel::new(mu, 8).unwrap(),
            rho: object.max_radius(),
            alpha,
            contacts,
        });
    };
    add(
        "paper-planar-mu0.3".into(),
        paper,
        Space::Planar,
        0.3,
        vec![6, 66, 28],
        &mut rng,
    );
    add(
        "paper-planar-mu0.03".into(),
        paper,
        Space::Planar,
        0.03,
        vec![6, 66, 28],
        &mut rng,
    );
    for (name, object, space) in [
        ("sphere6d", sphere, Space::Spatial),
        ("ellipsoid6d", ellipsoid, Space::Spatial),
        ("box6d", cuboid, Space::Spatial),
        ("ellipsoid-planar", ellipsoid, Space::Planar),
    ] {
        let p = common::problem(object, space, 0.5, 8);
        for (i, c) in common::force_closure_grasps(&p, &mut rng, 3, 3)
            .into_iter()
            .enumerate()
        {
            add(format!("{name}-{i}"), object, space, 0.5, c, &mut rng);
        }
        // One random grasp, force closure or not.
        let n = common::candidates(object, space).len();
        let c = (0..3).map(|_| rng.below(n)).collect();
        add(format!("{name}-random"), object, space, 0.5, c, &mut rng);
    }

    let dir = common::scratch("cross-reference");
    let input = dir.join("cases.json");
    let output = dir.join("results.json");
    std::fs::write(&input, cases_json(&cases)).unwrap();
    let run = Command::new(python())
        .arg(repo_root().join("bench/reference_qhull.py"))
        .arg("check")
        .arg(&input)
        .arg(&output)
        .output()
        .expect("running the Python reference");
    assert!(
        run.status.success(),
        "reference failed:\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&output).unwrap()).unwrap();
    let results = results["results"].as_array().unwrap();
    assert_eq!(results.len(), cases.len());
    let mut compared_regions = 0;
    for ((case, want), got) in cases.iter().zip(&expected).zip(results) {
        let id = &case.id;
        assert_eq!(got["id"].as_str().unwrap(), id);
        assert_eq!(
            got["force_closure"].as_bool().unwrap(),
            want.force_closure,
            "{id}: force closure"
        );
        let q = got["alpha_star"].as_f64().unwrap();
        assert!(
            (q - want.quality).abs() <= 1e-6 * want.quality.max(1e-12),
            "{id}: alpha* rust {} python {q}",
            want.quality
        );
        let eps = got["epsilon"].as_f64().unwrap();
        assert!(
            (eps - want.epsilon).abs() <= 1e-9,
            "{id}: epsilon rust {} python {eps}",
            want.epsilon
        );
        let py_regions: Vec<Vec<u32>> = got["icrs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| {
                r.as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_u64().unwrap() as u32)
                    .collect()
            })
            .collect();
        match &want.regions {
            Some(regions) => {
                assert!(
                    got["reason"].is_null(),
                    "{id}: python refused: {}",
                    got["reason"]
                );
                assert_eq!(&py_regions, regions, "{id}: regions differ");
                compared_regions += regions.len();
            }
            None => assert!(
                !got["reason"].is_null(),
                "{id}: python computed regions that rust refused"
            ),
        }
        println!(
            "{id}: agree (force closure {}, alpha* {:.6}, epsilon {:.6})",
            want.force_closure, want.quality, want.epsilon
        );
    }
    assert!(
        compared_regions >= 30,
        "only {compared_regions} regions compared"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
