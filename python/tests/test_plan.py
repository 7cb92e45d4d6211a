"""plan(config) gives the trajectory and summary of `icrflow plan`."""

import json

import numpy as np
import pytest

import icrflow
from conftest import CONFIG, read_toml


@pytest.fixture(scope="module")
def cli_plan(cli, tmp_path_factory):
    def run(name):
        out = tmp_path_factory.mktemp("plan")
        summary = json.loads(cli("plan", CONFIG / name, "--json", "--out", out).stdout)
        steps = json.loads((out / "trajectory.json").read_text())["steps"]
        return summary, steps

    return run


def nan_to_none(x):
    return None if isinstance(x, float) and np.isnan(x) else x


@pytest.mark.parametrize(
    "name", ["paper_sphere.toml", "ellipsoid_spatial.toml", "allegro_sphere.toml"]
)
def test_plan_equals_the_cli(name, cli_plan):
    summary, steps = cli_plan(name)
    p = icrflow.plan(CONFIG / name)
    assert p.summary == summary
    assert p.summary["completed"] and p.summary["switches"] > 0
    t = p.trajectory
    assert t["step"].tolist() == [s["step"] for s in steps]
    assert t["phase"].tolist() == [s["phase"] for s in steps]
    np.testing.assert_array_equal(t["rotation_deg"], [s["rotation_deg"] for s in steps])
    np.testing.assert_array_equal(t["quality"], [s["quality"] for s in steps])
    fingers = t["fingers"].tolist()
    assert fingers == [f["finger"] for f in steps[0]["fingers"]]
    for k, s in enumerate(steps):
        for i, f in enumerate(s["fingers"]):
            assert (None if t["contact"][k, i] < 0 else int(t["contact"][k, i])) == f["contact"]
            point = None if np.isnan(t["point"][k, i]).all() else t["point"][k, i].tolist()
            assert point == f["point"]
            normal = None if np.isnan(t["normal"][k, i]).all() else t["normal"][k, i].tolist()
            assert normal == f.get("normal")
            assert nan_to_none(float(t["angle_deg"][k, i])) == f["angle_deg"]
            assert nan_to_none(float(t["cap_angle_deg"][k, i])) == f["cap_angle_deg"]
            assert t["tip_rotation_deg"][k, i] == f["tip_rotation_deg"]
            assert t["tip_centre"][k, i].tolist() == f["tip_centre"]
            joints = t["joints_deg"][k, i]
            assert joints[: len(f["joints_deg"])].tolist() == f["joints_deg"]
    switches = [dict(s["switch"], step=s["step"]) for s in steps if "switch" in s]
    assert p.switches == switches
    assert len(p.switches) == summary["switches"]


def test_a_dict_plans_as_its_file():
    path = CONFIG / "paper_sphere.toml"
    cfg = read_toml(path)
    cfg["grasp"]["rho"] = None  # None: left out
    a, b = icrflow.plan(path), icrflow.plan(cfg)
    assert a.summary == b.summary
    for key in a.trajectory:
        np.testing.assert_array_equal(a.trajectory[key], b.trajectory[key])


def test_a_plan_that_stops_early_is_a_result():
    cfg = read_toml(CONFIG / "paper_sphere.toml")
    # Enough for the 72 rolling steps (the config's bound), not for the switches between.
    cfg["plan"]["max_steps"] = 80
    p = icrflow.plan(cfg)
    assert not p.summary["completed"]
    assert p.summary["stop_reason"]
    assert len(p.trajectory["step"]) == p.summary["steps"]
