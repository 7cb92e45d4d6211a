"""GraspProblem gives what `icrflow analyze --json` reports, for the same object and grasp."""

import re

import numpy as np
import pytest

import icrflow
from conftest import CONFIG, read_toml


def object_of(config_path, spec):
    """The object a config describes, built through the Python API."""
    shape = spec["shape"]
    segments = tuple(spec.get("segments", (72, 72)))
    if shape == "sphere":
        return icrflow.Object.sphere(spec["radius"], segments)
    if shape == "ellipsoid":
        return icrflow.Object.ellipsoid(tuple(spec["semi_axes"]), segments)
    if shape == "mesh":
        return icrflow.Object.mesh(config_path.parent / spec["path"])
    raise AssertionError(f"no Python constructor for {shape}")


def problem_of(config_path):
    cfg = read_toml(config_path)
    g = cfg["grasp"]
    obj = object_of(config_path, cfg["object"])
    problem = icrflow.GraspProblem(
        obj, g["friction"], g.get("cone_edges", 8), g.get("space", "spatial"), g.get("rho")
    )
    return obj, problem


CASES = ["paper_sphere.toml", "ellipsoid_spatial.toml", "paper_sphere_mu003.toml"]


@pytest.mark.parametrize("name", CASES)
def test_evaluate_equals_the_cli(name, analyze):
    path = CONFIG / name
    report = analyze(path)
    obj, problem = problem_of(path)
    assert problem.space == report["space"]
    assert problem.rho == pytest.approx(report["rho"], rel=1e-15)
    assert len(problem.candidates) == report["candidates"]
    assert len(obj.facet_points) == report["facets"]

    points = np.array([c["point"] for c in report["contacts"]])
    e = problem.evaluate(points)
    assert e.contacts.tolist() == [c["candidate"] for c in report["contacts"]]
    assert e.force_closure == report["force_closure"]
    assert e.closure == report["closure"]
    assert e.alpha_star == pytest.approx(report["quality"], rel=1e-12, abs=1e-15)
    assert e.epsilon == pytest.approx(report["epsilon"], rel=1e-12, abs=1e-15)
    assert e.hull_facets == report["hull_facets"]
    assert e.hull_normals.shape == (report["hull_facets"], problem.dim)
    np.testing.assert_allclose(e.points, points, rtol=0, atol=1e-15)
    # The same grasp by candidate index.
    by_index = problem.evaluate(e.contacts)
    assert by_index.alpha_star == e.alpha_star and by_index.epsilon == e.epsilon


@pytest.mark.parametrize("name", CASES)
def test_icrs_equal_the_cli(name, analyze):
    path = CONFIG / name
    report = analyze(path)
    _, problem = problem_of(path)
    points = np.array([c["point"] for c in report["contacts"]])
    if report["icr_status"] is not None:
        # No regions: the package exception carries the CLI's reason.
        with pytest.raises(icrflow.IcrflowError, match=re.escape(report["icr_status"])):
            problem.icrs(points, report["alpha"])
        return
    regions = problem.icrs(points, report["alpha"])
    assert len(regions) == len(report["contacts"])
    for region, contact in zip(regions, report["contacts"]):
        assert region.contact == contact["candidate"]
        assert region.indices.tolist() == contact["icr"]["indices"]
        np.testing.assert_allclose(region.points, np.array(contact["icr"]["points"]), rtol=0, atol=1e-15)
        assert len(region) == len(contact["icr"]["indices"]) > 1


def test_the_cases_cover_both_spaces_and_a_grasp_without_closure(analyze):
    reports = [analyze(CONFIG / n) for n in CASES]
    assert {r["space"] for r in reports} == {"planar", "spatial"}
    assert [r["force_closure"] for r in reports] == [True, True, False]


def test_any_pick_from_the_regions_keeps_the_margin(analyze):
    """The ICR guarantee through the API: one point per region, quality >= alpha."""
    path = CONFIG / "ellipsoid_spatial.toml"
    report = analyze(path)
    _, problem = problem_of(path)
    points = np.array([c["point"] for c in report["contacts"]])
    alpha = report["alpha"]
    regions = problem.icrs(points, alpha)
    rng = np.random.default_rng(7)
    picks = np.stack([rng.choice(r.indices, size=64) for r in regions], axis=1)
    result = problem.evaluate_batch(picks)
    assert result["force_closure"].all()
    assert (result["alpha_star"] >= alpha * (1 - 1e-9)).all()
