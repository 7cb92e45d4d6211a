"""Shared fixtures: the repository, the icrflow CLI the results are compared with, configs."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "config"

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - the test venv is 3.11
    tomllib = None


def cli_path() -> Path:
    """The CLI built by scripts/test.sh: $ICRFLOW_CLI, else $CARGO_TARGET_DIR/release/icrflow."""
    if "ICRFLOW_CLI" in os.environ:
        return Path(os.environ["ICRFLOW_CLI"])
    cache = Path(os.environ.get("ICRFLOW_CACHE", Path.home() / ".cache" / "icrflow"))
    target = Path(os.environ.get("CARGO_TARGET_DIR", cache / "target"))
    return target / "release" / "icrflow"


@pytest.fixture(scope="session")
def cli():
    """Runs the CLI; returns the CompletedProcess (text). The binary must exist: a missing one
    fails the tests (scripts/test.sh builds it), it never skips them."""
    exe = cli_path()
    assert exe.is_file(), f"the icrflow CLI is not built at {exe} (cargo build --release --bin icrflow)"

    def run(*args, check=True):
        p = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, cwd=ROOT)
        if check:
            assert p.returncode == 0, f"icrflow {' '.join(map(str, args))} failed: {p.stderr}"
        return p

    return run


@pytest.fixture(scope="session")
def analyze(cli):
    """`icrflow analyze CONFIG --json`, parsed."""
    cache = {}

    def run(config: Path):
        if config not in cache:
            # Exit status 2: the grasp is not force closure (or below alpha), an answer.
            p = cli("analyze", config, "--json", check=False)
            assert p.returncode in (0, 2), f"icrflow analyze {config} failed: {p.stderr}"
            cache[config] = json.loads(p.stdout)
        return cache[config]

    return run


def read_toml(path: Path) -> dict:
    assert tomllib is not None, "the tests need Python >= 3.11 (tomllib)"
    with open(path, "rb") as f:
        return tomllib.load(f)
