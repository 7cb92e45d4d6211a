#!/usr/bin/env python3
"""Independent Python reference for the grasp quality (alpha*) and the ICRs with a quality margin.

Written from shared/DESIGN.md section 3 ("Mathematics") only, without reading the Rust code, so
that the two implementations cross-check each other. numpy + scipy.spatial.ConvexHull (Qhull).

Usage:
    reference_qhull.py check CASES.json OUT.json
    reference_qhull.py bench CASES.json [--repeat N]

See bench/README.md for the input/output formats and the conventions.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import deque

import numpy as np
from scipy.spatial import ConvexHull

try:  # scipy >= 1.11 exports it here
    from scipy.spatial import QhullError
except ImportError:  # pragma: no cover
    from scipy.spatial.qhull import QhullError  # type: ignore

PLANAR_COMPONENTS = (0, 1, 5)  # (f_x, f_y, tau_z / rho) of the 6D wrench
TOL_REL = 1e-9  # tolerances are TOL_REL * max |w| over the hull's input points


# --------------------------------------------------------------------------------------------
# Wrenches
# --------------------------------------------------------------------------------------------

def tangent_basis(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t1, t2 for each outward unit normal (rows). Convention shared with the Rust side
    (`tangent_basis`, the tangent axis +z): t1 = normalize(ez x n), or normalize(ex x n) where
    |ez x n| < 1e-6 (the poles); t2 = n x t1."""
    n = np.asarray(normals, dtype=float)
    ez = np.array([0.0, 0.0, 1.0])
    ex = np.array([1.0, 0.0, 0.0])
    use_z = np.linalg.norm(np.cross(ez, n), axis=1) >= 1e-6
    ref = np.where(use_z[:, None], ez, ex)
    t1 = np.cross(ref, n)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    return t1, t2


def primitive_wrenches(points, normals, centre, mu, s, rho) -> np.ndarray:
    """(N, s, 6): w_ij = [f_ij; (p_i - c) x f_ij / rho], f_ij = -n + mu (cos t1 + sin t2)."""
    p = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    c = np.asarray(centre, dtype=float)
    t1, t2 = tangent_basis(n)
    theta = 2.0 * np.pi * np.arange(s) / s
    cos = np.cos(theta)[None, :, None]
    sin = np.sin(theta)[None, :, None]
    f = -n[:, None, :] + mu * (cos * t1[:, None, :] + sin * t2[:, None, :])  # (N, s, 3)
    r = (p - c)[:, None, :]
    tau = np.cross(np.broadcast_to(r, f.shape), f) / rho
    return np.concatenate([f, tau], axis=2)


def object_wrenches(points, normals, centre, rho) -> np.ndarray:
    """(K, 6): o_k = [n_k; (l_k - c) x n_k / rho]."""
    l = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    c = np.asarray(centre, dtype=float)
    return np.concatenate([n, np.cross(l - c, n) / rho], axis=1)


def project(w: np.ndarray, space: str) -> np.ndarray:
    if space == "spatial":
        return w
    if space == "planar":
        return w[..., PLANAR_COMPONENTS]
    raise ValueError(f"unknown space {space!r} (expected 'spatial' or 'planar')")


class Case:
    """Per-case data computed once: OWS points and every candidate's primitive wrenches."""

    def __init__(self, d: dict):
        self.id = d["id"]
        self.space = d["space"]
        self.mu = float(d["mu"])
        self.s = int(d["cone_edges"])
        self.rho = float(d["rho"])
        self.alpha = float(d["alpha"])
        centre = d["centre"]
        self.ows = np.ascontiguousarray(
            project(object_wrenches(d["ows_points"], d["ows_normals"], centre, self.rho), self.space))
        self.cand = np.ascontiguousarray(project(
            primitive_wrenches(d["candidate_points"], d["candidate_normals"], centre,
                               self.mu, self.s, self.rho), self.space))  # (N, s, dim)
        self.neighbours = [list(map(int, nb)) for nb in d["candidate_neighbours"]]
        self.contacts = [int(i) for i in d["contacts"]]
        self.dim = self.cand.shape[2]
        n = self.cand.shape[0]
        if len(self.neighbours) != n:
            raise ValueError(f"{self.id}: {len(self.neighbours)} neighbour lists for {n} candidates")
        for i in self.contacts:
            if not 0 <= i < n:
                raise ValueError(f"{self.id}: contact index {i} out of range 0..{n}")


# --------------------------------------------------------------------------------------------
# Hull, force closure, alpha*, epsilon
# --------------------------------------------------------------------------------------------

class GraspHull:
    """GWS hull of the contacts' primitive wrenches, with merged facets.

    A: (F, dim) unit outward normals, b: (F,) offsets (a_f . w <= b_f inside), on: (F, P) bool,
    point p lies on facet f. F counts merged facets (scipy's simplices grouped by the set of input
    points lying on their hyperplane, within tol)."""

    def __init__(self, case: Case, contacts=None):
        contacts = case.contacts if contacts is None else contacts
        self.points = case.cand[contacts].reshape(-1, case.dim)  # contact-major: row = i*s + j
        self.s = case.s
        self.tol = TOL_REL * float(np.max(np.linalg.norm(self.points, axis=1)))
        self.degenerate = False
        self.error = None
        try:
            hull = ConvexHull(self.points)
        except (QhullError, ValueError) as e:  # lower-dimensional input, too few points
            self.degenerate = True
            self.error = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            self.A = np.zeros((0, case.dim))
            self.b = np.zeros(0)
            self.on = np.zeros((0, len(self.points)), dtype=bool)
            self.vertices = np.zeros(0, dtype=int)
            return
        eq = hull.equations
        a_all, b_all = eq[:, :-1], -eq[:, -1]
        on_all = np.abs(self.points @ a_all.T - b_all) <= self.tol  # (P, S)
        # group simplices of one merged facet: same on-set of input points (one bytes key each)
        keys = np.ascontiguousarray(np.packbits(on_all, axis=0).T)  # (S, ceil(P/8)) uint8
        keys = keys.view(np.dtype((np.void, keys.shape[1]))).ravel()
        _, first = np.unique(keys, return_index=True)
        first = np.sort(first)
        self.A = a_all[first]
        self.b = b_all[first]
        self.on = on_all[:, first].T  # (F, P)
        self.vertices = hull.vertices

    @property
    def n_facets(self) -> int:
        return int(self.A.shape[0])

    def force_closure(self) -> bool:
        return (not self.degenerate) and self.n_facets > 0 and bool(np.min(self.b) > self.tol)

    def epsilon(self) -> float:
        return 0.0 if self.degenerate or self.n_facets == 0 else float(np.min(self.b))


def support(A: np.ndarray, ows: np.ndarray) -> np.ndarray:
    """h_f = max_k a_f . o_k, one dense matrix product."""
    return (A @ ows.T).max(axis=1)


def alpha_star_from(hull: GraspHull, h: np.ndarray) -> float:
    """0 if not force closure; min over h_f > 0 of b_f / h_f; inf if no h_f > 0."""
    if not hull.force_closure():
        return 0.0
    pos = h > 0.0
    if not np.any(pos):
        return math.inf
    return float(np.min(hull.b[pos] / h[pos]))


def alpha_star(case: Case, contacts=None) -> float:
    """The timed evaluation: contact wrenches -> hull -> force closure -> support -> alpha*."""
    hull = GraspHull(case, contacts)
    if not hull.force_closure():
        return 0.0
    return alpha_star_from(hull, support(hull.A, case.ows))


# --------------------------------------------------------------------------------------------
# ICRs (zone rule)
# --------------------------------------------------------------------------------------------

def search_zones(hull: GraspHull, contact_slot: int, dim: int) -> np.ndarray:
    """Zones Z_omega of one contact as a bool matrix (zones, facets): row z marks the facets
    whose half-spaces H_f+ intersect to zone z. One zone per hull vertex omega of the contact.

    omega is a vertex iff the normals of the facets it lies on span R^dim (its normal cone is
    full-dimensional); this drops points lying on the boundary but not extreme (duplicates of
    a vertex give the same zone and are deduplicated)."""
    s = hull.s
    zones: dict[bytes, np.ndarray] = {}
    for p in range(contact_slot * s, (contact_slot + 1) * s):
        col = hull.on[:, p]
        fs = np.flatnonzero(col)
        if fs.size < dim:
            continue
        if np.linalg.matrix_rank(hull.A[fs], tol=1e-9) < dim:
            continue
        zones.setdefault(col.tobytes(), col)
    if not zones:
        return np.zeros((0, hull.n_facets), dtype=bool)
    return np.array(list(zones.values()), dtype=bool)


def icr_for_contact(case: Case, hull: GraspHull, thresh: np.ndarray, zones: np.ndarray,
                    start: int) -> list[int]:
    """Connected component of `start` (breadth-first over the neighbour graph, expanding only
    through members) of the candidates that have, for every zone, one primitive wrench w with
    a_f . w >= alpha h_f - tol for all facets f of the zone. Membership is evaluated only for
    the candidates the growth reaches, one BFS layer at a time (vectorised per layer)."""
    At = np.ascontiguousarray(hull.A.T)
    Zt = np.ascontiguousarray(zones.T, dtype=float)  # (F, zones)

    def members(qs: list[int]) -> np.ndarray:
        if Zt.shape[1] == 0:
            return np.ones(len(qs), dtype=bool)
        miss = (case.cand[qs] @ At < thresh).astype(float)  # (m, s, F): wrench misses H_f+
        viol = miss @ Zt  # (m, s, zones): facets of the zone that the wrench misses
        in_zone = (viol == 0.0).any(axis=1)  # (m, zones): some wrench of q inside the zone
        return in_zone.all(axis=1)

    if not members([start])[0]:
        return []
    seen = {start}
    region = [start]
    layer = [start]
    while layer:
        nxt = []
        for q in layer:
            for r in case.neighbours[q]:
                if r not in seen:
                    seen.add(r)
                    nxt.append(r)
        if not nxt:
            break
        ok = members(nxt)
        layer = [r for r, m in zip(nxt, ok) if m]
        region.extend(layer)
    return sorted(region)


def evaluate(case: Case) -> dict:
    hull = GraspHull(case)
    n_c = len(case.contacts)
    res = {"id": case.id, "force_closure": False, "alpha_star": 0.0, "epsilon": hull.epsilon(),
           "facets": hull.n_facets, "icrs": [[] for _ in range(n_c)], "reason": None}
    if hull.degenerate:
        res["reason"] = f"degenerate grasp wrench set (Qhull: {hull.error}); not force closure"
        return res
    if not hull.force_closure():
        res["reason"] = "not force closure (origin not strictly inside the grasp wrench hull)"
        return res
    h = support(hull.A, case.ows)
    a_star = alpha_star_from(hull, h)
    res["force_closure"] = True
    res["alpha_star"] = a_star if math.isfinite(a_star) else None
    if not case.alpha <= a_star:
        res["reason"] = f"alpha = {case.alpha} exceeds alpha* = {a_star}"
        return res
    res["icrs"] = icrs(case, hull, h)
    return res


def icrs(case: Case, hull: GraspHull, h: np.ndarray) -> list[list[int]]:
    thresh = case.alpha * h - hull.tol
    return [icr_for_contact(case, hull, thresh, search_zones(hull, i, case.dim), c)
            for i, c in enumerate(case.contacts)]


def icr_pipeline(case: Case):
    """The timed ICR query: contact wrenches -> hull -> support -> alpha* -> zones -> BFS."""
    hull = GraspHull(case)
    if not hull.force_closure():
        return None
    h = support(hull.A, case.ows)
    if not case.alpha <= alpha_star_from(hull, h):
        return None
    return icrs(case, hull, h)


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------

def load_cases(path: str) -> list[Case]:
    with open(path) as fh:
        data = json.load(fh)
    return [Case(d) for d in data["cases"]]


def cmd_check(args) -> int:
    results = [evaluate(c) for c in load_cases(args.cases)]
    with open(args.out, "w") as fh:
        json.dump({"results": results}, fh, indent=1, allow_nan=False)
        fh.write("\n")
    for r in results:
        print(f"{r['id']}: force_closure={r['force_closure']} alpha*={r['alpha_star']} "
              f"epsilon={r['epsilon']:.6g} facets={r['facets']} "
              f"icr_sizes={[len(x) for x in r['icrs']]}"
              + (f" ({r['reason']})" if r["reason"] else ""), file=sys.stderr)
    return 0


def _time_us(fn, repeat: int) -> list[float]:
    fn()  # warm-up
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter_ns()
        fn()
        out.append((time.perf_counter_ns() - t0) / 1000.0)
    return out


def cmd_bench(args) -> int:
    for case in load_cases(args.cases):  # precomputation (OWS, candidate wrenches) not timed
        ta = _time_us(lambda: alpha_star(case), args.repeat)
        ti = _time_us(lambda: icr_pipeline(case), args.repeat)
        print(json.dumps({"id": case.id,
                          "alpha_star_median_us": float(np.median(ta)),
                          "alpha_star_min_us": float(np.min(ta)),
                          "icr_median_us": float(np.median(ti)),
                          "repeat": args.repeat}), flush=True)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("check", help="force closure, alpha*, epsilon, ICRs -> OUT.json")
    c.add_argument("cases")
    c.add_argument("out")
    c.set_defaults(fn=cmd_check)
    b = sub.add_parser("bench", help="time alpha* and the ICR query; JSON lines on stdout")
    b.add_argument("cases")
    b.add_argument("--repeat", type=int, default=100)
    b.set_defaults(fn=cmd_bench)
    args = ap.parse_args(argv)
    if getattr(args, "repeat", 1) < 1:
        ap.error("--repeat must be >= 1")
    return args.fn(args)


if __name__ == "__main__":
    sys.exit(main())
