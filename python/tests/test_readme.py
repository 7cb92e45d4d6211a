"""The README's Python example runs as written (from the repository root)."""

import contextlib
import io
import os
import re

from conftest import ROOT


def readme_example() -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split("## From Python", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(blocks) == 1, "the README's From Python section has one Python example"
    return blocks[0]


def test_the_readme_example_runs():
    code = readme_example()
    assert 8 <= len([l for l in code.splitlines() if l.strip()]) <= 14
    out = io.StringIO()
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(code, "README.md", "exec"), {})
    finally:
        os.chdir(cwd)
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("force closure True, alpha* = ")
    alpha = float(re.search(r"alpha\* = ([0-9.]+)", lines[0]).group(1))
    smallest = float(lines[1].rsplit(" ", 1)[1])
    assert lines[1].startswith("10000 grasps from the ICRs")
    # The ICR guarantee, printed to 4 decimals.
    assert smallest >= round(alpha / 2, 4) - 1e-4
