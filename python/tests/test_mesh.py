"""A mesh loaded with trimesh works: from_arrays equals reading the same mesh from a file,
and both equal the CLI on a config naming that file."""

import json

import numpy as np
import pytest
import trimesh

import icrflow


# Generic points (no two facets nearly as near), so float32 (STL) and float64 meshes snap alike.
GRASP = np.array([[0.041, 0.003, 0.002], [-0.019, 0.036, -0.004], [-0.021, -0.034, 0.011]])


@pytest.fixture(scope="module")
def ico(tmp_path_factory):
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.04)
    assert mesh.is_watertight
    path = tmp_path_factory.mktemp("mesh") / "ico.stl"
    mesh.export(path)
    return mesh, path


def test_from_arrays_of_a_trimesh_equals_the_file(ico):
    mesh, path = ico
    a = icrflow.Object.from_arrays(mesh.vertices, mesh.faces, name="ico")
    b = icrflow.Object.mesh(path)
    assert len(a.facet_points) == len(mesh.faces) == len(b.facet_points)
    assert a.volume == pytest.approx(mesh.volume, rel=1e-9)
    assert b.volume == pytest.approx(mesh.volume, rel=1e-6)  # STL stores float32
    np.testing.assert_allclose(a.centre_of_mass, mesh.center_mass, atol=1e-12)
    pa = icrflow.GraspProblem(a, 0.5)
    pb = icrflow.GraspProblem(b, 0.5)
    ea, eb = pa.evaluate(GRASP), pb.evaluate(GRASP)
    assert ea.contacts.tolist() == eb.contacts.tolist()
    assert ea.force_closure and eb.force_closure
    assert ea.alpha_star == pytest.approx(eb.alpha_star, rel=1e-5)


def test_a_trimesh_mesh_equals_the_cli(ico, tmp_path, cli):
    mesh, path = ico
    config = tmp_path / "ico.toml"
    config.write_text(
        f"""[object]
shape = "mesh"
path = "{path}"

[grasp]
space = "spatial"
friction = 0.5
alpha = 0.05
contacts = [
  {{ finger = 1, point = {GRASP[0].tolist()} }},
  {{ finger = 2, point = {GRASP[1].tolist()} }},
  {{ finger = 3, point = {GRASP[2].tolist()} }},
]
"""
    )
    report = json.loads(cli("analyze", config, "--json").stdout)
    problem = icrflow.GraspProblem(icrflow.Object.mesh(path), 0.5)
    e = problem.evaluate(GRASP)
    assert e.contacts.tolist() == [c["candidate"] for c in report["contacts"]]
    assert e.alpha_star == pytest.approx(report["quality"], rel=1e-12)
    regions = problem.icrs(e.contacts, report["alpha"])
    assert [r.indices.tolist() for r in regions] == [c["icr"]["indices"] for c in report["contacts"]]
    # And through trimesh's arrays (float64, not the STL's float32): the same candidates.
    from_arrays = icrflow.GraspProblem(icrflow.Object.from_arrays(mesh.vertices, mesh.faces), 0.5)
    assert from_arrays.evaluate(e.points).contacts.tolist() == e.contacts.tolist()


def test_polygons_of_different_sizes(tmp_path):
    # A cube of six quads, as a list of lists.
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float) * 0.02
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    cube = icrflow.Object.from_arrays(v, faces)
    assert len(cube.faces) == 6 and all(len(f) == 4 for f in cube.faces)
    assert cube.volume == pytest.approx(8e-6, rel=1e-12)
