#!/usr/bin/env python3
"""Times the Python package against the Rust criterion figure and the numpy/Qhull reference.

    python_bench.py [--criterion DIR] [--grasps N] [--reference-grasps M]

Case: the paper's sphere (72 x 72, 5184 facets), spatial (6D), mu = 0.5, s = 8, rho = its
radius, the contacts of grasp/benches/quality.rs's `alpha6d-sphere72x72` (three contacts at
0/120/240 degrees about z + 0.1 rad, tilted +-0.3, snapped to facets).

1. One call: `problem.evaluate(indices)` (and with points, snapped), median and minimum of
   single calls, against criterion's `grasp/alpha6d-sphere72x72/alpha_star` of the same run
   (read from DIR, `$CARGO_TARGET_DIR/criterion`): the binding's overhead.
2. Batch throughput: N force-closure grasps (one candidate from each ICR of that grasp at
   alpha*/2, seeded) by `evaluate_batch` on 1 and 2 threads, grasps per second (best of 3),
   and M of them through bench/reference_qhull.py's `alpha_star` (numpy + scipy Qhull, one
   thread), with the largest relative difference of the two alpha*.
Prints a markdown table and one JSON line.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import icrflow

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import reference_qhull  # noqa: E402


def spread_points(obj: icrflow.Object, tilt: float) -> np.ndarray:
    """grasp/benches/quality.rs `spread_contacts`: the points whose nearest facets are used."""
    out = []
    for k in range(3):
        t = 2 * math.pi * k / 3 + 0.1
        z = -tilt if k == 1 else tilt
        out.append(obj.centre_of_mass + np.array([math.cos(t), math.sin(t), z]) * obj.max_radius * 2)
    return np.array(out)


def time_calls(fn, repeat: int) -> list[float]:
    fn()
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter_ns()
        fn()
        out.append((time.perf_counter_ns() - t0) / 1000.0)
    return out


def criterion_us(root: Path | None, bench: str) -> tuple[float, float] | None:
    """(median, fastest sample) in us of a criterion benchmark, if it ran."""
    if root is None:
        return None
    d = root / "grasp" / bench / "new"
    try:
        est = json.loads((d / "estimates.json").read_text())
        sample = json.loads((d / "sample.json").read_text())
    except OSError:
        return None
    fastest = min(t / n for t, n in zip(sample["times"], sample["iters"]))
    return est["median"]["point_estimate"] / 1000.0, fastest / 1000.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--criterion", type=Path, help="criterion's output directory")
    ap.add_argument("--grasps", type=int, default=20_000)
    ap.add_argument("--reference-grasps", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=2000)
    args = ap.parse_args()

    obj = icrflow.Object.sphere(0.0475, (72, 72))
    problem = icrflow.GraspProblem(obj, 0.5, 8, "spatial")
    points = spread_points(obj, 0.3)
    indices, _ = problem.snap(points)
    e = problem.evaluate(indices)
    assert e.force_closure, "the benchmark grasp is force closure"

    # 1. One call.
    by_index = time_calls(lambda: problem.evaluate(indices), args.repeat)
    by_point = time_calls(lambda: problem.evaluate(points), args.repeat // 4)
    rust = criterion_us(args.criterion, "alpha6d-sphere72x72_alpha_star")

    # 2. Batch throughput.
    regions = problem.icrs(indices, e.alpha_star / 2)
    rng = np.random.default_rng(23)
    grasps = np.stack([rng.choice(r.indices, args.grasps) for r in regions], axis=1)
    rates = {}
    results = None
    for threads in (1, 2):
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            results = problem.evaluate_batch(grasps, threads=threads)
            best = min(best, time.perf_counter() - t0)
        rates[threads] = len(grasps) / best
    assert results is not None and results["force_closure"].all()

    case = reference_qhull.Case({
        "id": "sphere72x72", "space": "spatial", "mu": 0.5, "cone_edges": 8,
        "rho": problem.rho, "alpha": 0.0, "centre": obj.centre_of_mass.tolist(),
        "ows_points": obj.facet_points.tolist(), "ows_normals": obj.facet_normals.tolist(),
        "candidate_points": problem.candidates.tolist(),
        "candidate_normals": problem.candidate_normals.tolist(),
        "candidate_neighbours": [[] for _ in range(len(problem.candidates))],
        "contacts": indices.tolist(),
    })
    sub = grasps[: args.reference_grasps]
    t0 = time.perf_counter()
    ref = np.array([reference_qhull.alpha_star(case, list(map(int, g))) for g in sub])
    ref_rate = len(sub) / (time.perf_counter() - t0)
    ours = results["alpha_star"][: len(sub)]
    rel = float(np.max(np.abs(ours - ref) / np.abs(ref)))

    med_i, min_i = statistics.median(by_index), min(by_index)
    med_p = statistics.median(by_point)
    print("| what | figure |")
    print("|---|---|")
    print(f"| one call, `evaluate(indices)` (Python) | median {med_i:.1f} us, min {min_i:.1f} us |")
    print(f"| one call, `evaluate(points)` (Python, 3 points snapped among 5184) | median {med_p:.1f} us |")
    if rust:
        print(f"| criterion `alpha6d-sphere72x72/alpha_star` (Rust) | median {rust[0]:.1f} us, min {rust[1]:.1f} us |")
        print(f"| binding overhead (medians, minimums) | {med_i - rust[0]:+.1f} us, {min_i - rust[1]:+.1f} us |")
    print(f"| `evaluate_batch`, 1 thread, {len(grasps)} grasps | {rates[1]:,.0f} grasps/s ({1e6 / rates[1]:.1f} us each) |")
    print(f"| `evaluate_batch`, 2 threads | {rates[2]:,.0f} grasps/s ({rates[2] / rates[1]:.2f}x) |")
    print(f"| reference_qhull.py `alpha_star`, 1 thread, {len(sub)} of them | {ref_rate:,.0f} grasps/s |")
    print(f"| speed-up, batch 1 thread / 2 threads over the reference | {rates[1] / ref_rate:.0f}x / {rates[2] / ref_rate:.0f}x |")
    print(f"| largest relative difference of alpha* (package vs reference) | {rel:.1e} |")
    print(json.dumps({
        "evaluate_indices_median_us": med_i, "evaluate_indices_min_us": min_i,
        "evaluate_points_median_us": med_p,
        "criterion_median_us": rust[0] if rust else None, "criterion_min_us": rust[1] if rust else None,
        "batch_grasps_per_s": {str(k): v for k, v in rates.items()},
        "reference_grasps_per_s": ref_rate, "alpha_rel_diff": rel,
        "cpus": os.cpu_count(), "grasps": len(grasps),
    }))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
