#!/usr/bin/env python3
"""Markdown table of one `bench/compare.sh` run: criterion medians (Rust) beside the Python
reference's medians for the same cases. Usage: table.py CRITERION_DIR PYTHON_JSON_LINES"""
import json
import pathlib
import sys

crit = pathlib.Path(sys.argv[1]) / "grasp"
py = {}
for line in pathlib.Path(sys.argv[2]).read_text().splitlines():
    if line.strip().startswith("{"):
        d = json.loads(line)
        py[d["id"]] = d


def median_us(case: str, what: str):
    f = crit / f"{case}_{what}" / "new" / "estimates.json"
    if not f.exists():
        return None
    return json.loads(f.read_text())["median"]["point_estimate"] / 1e3


def fmt(us):
    if us is None:
        return "-"
    return f"{us / 1e3:.2f} ms" if us >= 1000 else f"{us:.1f} us"


cases = sorted({p.name.split("_", 1)[0] for p in crit.iterdir() if p.is_dir() and "_" in p.name})
print("| case | alpha* (Rust) | hull, as evaluated | hull, beneath-beyond | support, tree "
      "| support, dense | ICR query (Rust) | ICRs given alpha* | alpha* (Python) "
      "| ICR query (Python) | alpha* speed-up |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for c in cases:
    a = median_us(c, "alpha_star")
    p = py.get(c, {})
    pa, pi = p.get("alpha_star_median_us"), p.get("icr_median_us")
    speed = f"{pa / a:.0f}x" if a and pa else "-"
    print(f"| {c} | {fmt(a)} | {fmt(median_us(c, 'hull_contacts'))} "
          f"| {fmt(median_us(c, 'hull_only'))} | {fmt(median_us(c, 'support_only'))} "
          f"| {fmt(median_us(c, 'support_dense'))} | {fmt(median_us(c, 'icrs_query'))} "
          f"| {fmt(median_us(c, 'icrs_only'))} | {fmt(pa)} | {fmt(pi)} | {speed} |")
