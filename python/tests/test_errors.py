"""Bad input raises ValueError (or FileNotFoundError) naming what is wrong; what cannot be
computed raises icrflow.IcrflowError with the CLI's message; nothing panics."""

import math

import numpy as np
import pytest

import icrflow
from conftest import CONFIG, read_toml


@pytest.fixture(scope="module")
def problem():
    return icrflow.GraspProblem(icrflow.Object.sphere(0.05, (12, 12)), 0.5)


GOOD = np.array([[0.05, 0.0, 0.0], [-0.025, 0.043, 0.0], [-0.025, -0.043, 0.0]])


@pytest.mark.parametrize(
    "contacts, message",
    [
        (np.zeros((3, 2)), r"contacts: expected an \(n, 3\) float array .* got an array of shape \(3, 2\)"),
        (np.zeros(3), r"got an array of shape \(3,\)"),
        (np.zeros((0, 3)), "a grasp needs at least one contact"),
        (np.array([[0.0, 0.0, math.nan], [1.0, 0.0, 0.0]]), r"contacts\[0, 2\]: must be finite, got NaN"),
        (np.array([[0.0, math.inf, 0.0]]), r"contacts\[0, 1\]: must be finite, got inf"),
        (np.array([0, 1, 10_000]), r"contacts\[2\]: candidate 10000 does not exist \(the problem has 144 candidates"),
        (np.array([0, -1, 2]), r"contacts\[1\]: candidate -1 does not exist"),
        (np.array([True, False]), "contacts: expected numbers, got an array of dtype bool"),
        ("three points", "contacts: expected numbers"),
        ([[0.0, 1.0], [2.0]], "contacts: not an array of numbers"),
    ],
)
def test_bad_contacts(problem, contacts, message):
    with pytest.raises(ValueError, match=message):
        problem.evaluate(contacts)


def test_bad_batches(problem):
    with pytest.raises(ValueError, match=r"expected an \(N, n, 3\) float array .* got an array of shape \(4, 3\)"):
        problem.evaluate_batch(np.zeros((4, 3)))
    bad = np.zeros((4, 3, 3))
    bad[2, 1, 0] = math.nan
    with pytest.raises(ValueError, match=r"contacts\[2, 1, 0\]: must be finite"):
        problem.evaluate_batch(bad)
    with pytest.raises(ValueError, match=r"contacts\[1, 2\]: candidate 144 does not exist"):
        problem.evaluate_batch(np.array([[0, 1, 2], [3, 4, 144]]))
    with pytest.raises(ValueError, match="threads: must be at least 1"):
        problem.evaluate_batch(np.zeros((1, 3), dtype=np.int64), threads=0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(friction=-0.1), "friction: friction coefficient must be finite and >= 0, got -0.1"),
        (dict(friction=math.nan), "friction: friction coefficient must be finite and >= 0"),
        (dict(friction=0.5, cone_edges=2), "cone_edges: a linearised friction cone needs 3 to 64 edges, got 2"),
        (dict(friction=0.5, space="3d"), 'space: "3d" is not a wrench space; use "spatial"'),
        (dict(friction=0.5, rho=0.0), "rho: torque normalisation length rho must be finite and > 0, got 0"),
    ],
)
def test_bad_problems(kwargs, message):
    with pytest.raises(ValueError, match=message):
        icrflow.GraspProblem(icrflow.Object.sphere(0.05, (12, 12)), **kwargs)


def test_bad_objects(tmp_path):
    with pytest.raises(FileNotFoundError, match="cannot read .*no-such-mesh.stl"):
        icrflow.Object.mesh(tmp_path / "no-such-mesh.stl")
    with pytest.raises(ValueError, match="unsupported mesh file .*mesh.ply: the extension must be .stl or .obj"):
        icrflow.Object.mesh(tmp_path / "mesh.ply")
    (tmp_path / "empty.stl").write_bytes(b"")
    with pytest.raises(ValueError, match="cannot parse .*empty.stl as STL: the file is empty"):
        icrflow.Object.mesh(tmp_path / "empty.stl")
    with pytest.raises(ValueError, match="radius must be positive and finite, got -1"):
        icrflow.Object.sphere(-1.0)
    with pytest.raises(ValueError, match=r"segments: needs at least \(3, 2\)"):
        icrflow.Object.sphere(0.05, (2, 2))
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    with pytest.raises(ValueError, match=r"open surface: edge \(.*\) of face 0 .* belongs to no other face"):
        icrflow.Object.from_arrays(tri, np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match=r"faces\[0\]: vertex index 3 out of range \(there are 3 vertices\)"):
        icrflow.Object.from_arrays(tri, np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match=r"vertices: expected an array of shape \(V, 3\), got an array of shape \(3, 2\)"):
        icrflow.Object.from_arrays(tri[:, :2], np.array([[0, 1, 2]]))
    nan = tri.copy()
    nan[1, 1] = math.nan
    with pytest.raises(ValueError, match=r"vertices\[1, 1\]: must be finite"):
        icrflow.Object.from_arrays(nan, np.array([[0, 1, 2]]))


def test_regions_that_cannot_be(problem):
    e = problem.evaluate(GOOD)
    assert e.force_closure
    with pytest.raises(icrflow.IcrflowError, match=r"the margin alpha = 10 exceeds the grasp's quality alpha\* = "):
        problem.icrs(GOOD, 10.0)
    with pytest.raises(ValueError, match="alpha: must be finite and >= 0, got -1"):
        problem.icrs(GOOD, -1.0)
    with pytest.raises(icrflow.IcrflowError, match="the grasp is not force closure"):
        problem.icrs(GOOD[:2], 0.0)


BASE = read_toml(CONFIG / "paper_sphere.toml")


def with_changes(**sections):
    cfg = {k: dict(v) if isinstance(v, dict) else v for k, v in BASE.items()}
    for section, changes in sections.items():
        cfg[section] = {**cfg.get(section, {}), **changes}
    return cfg


@pytest.mark.parametrize(
    "config, message",
    [
        (with_changes(grasp={"friction": -0.3}), "grasp.friction"),
        (with_changes(grasp={"bogus": 1}), "unknown field `bogus`"),
        (with_changes(object={"radius": "big"}), "invalid config"),
        (with_changes(grasp={"alpha": object()}), r"config.grasp.alpha: a object cannot be a config value"),
        ({"grasp": BASE["grasp"]}, "missing field `object`"),
        (42, "config: expected a path or a dict"),
    ],
)
def test_bad_configs(config, message):
    with pytest.raises(ValueError, match=message):
        icrflow.plan(config)


def test_a_missing_config_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="cannot read config .*nope.toml"):
        icrflow.plan(tmp_path / "nope.toml")


def test_a_refused_scenario_has_the_cli_message(cli):
    path = CONFIG / "paper_sphere_mu003.toml"
    p = cli("plan", path, "--out", "/tmp/icrflow-py-test-refused", check=False)
    # Not force closure is an answer, exit status 2 (0 done, 1 error), said on stderr.
    assert p.returncode == 2
    message = p.stderr.strip().removeprefix("plan: ")
    assert "not force closure" in message
    with pytest.raises(icrflow.IcrflowError) as e:
        icrflow.plan(path)
    assert str(e.value) == message
