"""evaluate_batch equals evaluating the grasps one by one, on any number of threads."""

import numpy as np
import pytest

import icrflow


@pytest.fixture(scope="module")
def sphere_problem():
    return icrflow.GraspProblem(icrflow.Object.sphere(0.0475, (24, 24)), 0.5, 8, "spatial")


def random_grasps(problem, n_grasps, n_contacts, seed):
    rng = np.random.default_rng(seed)
    return rng.integers(0, len(problem.candidates), size=(n_grasps, n_contacts))


@pytest.mark.parametrize("n_contacts", [3, 4])
def test_batch_of_indices_equals_the_loop(sphere_problem, n_contacts):
    grasps = random_grasps(sphere_problem, 300, n_contacts, seed=n_contacts)
    batch = sphere_problem.evaluate_batch(grasps)
    loop = [sphere_problem.evaluate(g) for g in grasps]
    np.testing.assert_array_equal(batch["alpha_star"], [e.alpha_star for e in loop])
    np.testing.assert_array_equal(batch["epsilon"], [e.epsilon for e in loop])
    np.testing.assert_array_equal(batch["force_closure"], [e.force_closure for e in loop])
    assert batch["force_closure"].dtype == np.bool_
    # Random grasps: some hold, some do not, so the comparison covers both.
    assert 0 < batch["force_closure"].sum() < len(grasps)


def test_batch_of_points_equals_the_loop(sphere_problem):
    grasps = random_grasps(sphere_problem, 200, 3, seed=11)
    rng = np.random.default_rng(12)
    points = sphere_problem.candidates[grasps] * 1.01 + rng.normal(0, 1e-4, size=grasps.shape + (3,))
    batch = sphere_problem.evaluate_batch(points)
    loop = [sphere_problem.evaluate(p) for p in points]
    np.testing.assert_array_equal(batch["alpha_star"], [e.alpha_star for e in loop])
    np.testing.assert_array_equal(batch["epsilon"], [e.epsilon for e in loop])
    # Snapping agrees with snap().
    assert [e.contacts.tolist() for e in loop] == [sphere_problem.snap(p)[0].tolist() for p in points]


def test_threads_do_not_change_the_results(sphere_problem):
    grasps = random_grasps(sphere_problem, 101, 3, seed=5)
    one = sphere_problem.evaluate_batch(grasps, threads=1)
    for threads in (2, 3, 200):
        other = sphere_problem.evaluate_batch(grasps, threads=threads)
        for key in ("alpha_star", "epsilon", "force_closure"):
            np.testing.assert_array_equal(one[key], other[key])


def test_non_contiguous_and_other_dtypes_read_the_same(sphere_problem):
    grasps = random_grasps(sphere_problem, 50, 3, seed=9)
    reference = sphere_problem.evaluate_batch(grasps)["alpha_star"]
    wide = np.zeros((50, 6), dtype=np.int64)
    wide[:, ::2] = grasps  # a strided view
    assert not wide[:, ::2].flags["C_CONTIGUOUS"]
    np.testing.assert_array_equal(sphere_problem.evaluate_batch(wide[:, ::2])["alpha_star"], reference)
    np.testing.assert_array_equal(sphere_problem.evaluate_batch(grasps.astype(np.int32))["alpha_star"], reference)
    np.testing.assert_array_equal(sphere_problem.evaluate_batch(grasps.tolist())["alpha_star"], reference)


def test_an_empty_batch_is_empty(sphere_problem):
    out = sphere_problem.evaluate_batch(np.zeros((0, 3), dtype=np.int64))
    assert out["alpha_star"].shape == (0,)
