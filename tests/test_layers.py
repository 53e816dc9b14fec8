"""The layers of the README's Layout section hold: import-linter's contracts in pyproject.toml
(each layer imports only the layers below it; Hydra only at the edge), checked on the code as it
is, and a contract that import-linter really enforces (a planted upward import is reported)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))


def lint(root: Path) -> subprocess.CompletedProcess:
    if not Path(LINT).exists():
        pytest.fail("lint-imports is missing: pip install -e '.[test]'")
    return subprocess.run([LINT, "--no-cache"], cwd=root, capture_output=True, text=True, timeout=300,
                          env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"})  # fmt: skip


def test_the_layers_hold():
    done = lint(ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "0 broken" in done.stdout


def test_an_upward_import_is_reported(tmp_path):
    copy = tmp_path / "repo"
    shutil.copytree(ROOT, copy, ignore=shutil.ignore_patterns(".git", ".venv*", "outputs", "multirun", "__pycache__", "experiments", "tests"))
    kinematics = copy / "zrp_ga" / "model" / "kinematics.py"
    kinematics.write_text(kinematics.read_text() + "\nimport zrp_ga.algorithms.ga  # planted\n")
    done = lint(copy)
    assert done.returncode != 0
    assert "zrp_ga.model.kinematics -> zrp_ga.algorithms.ga" in done.stdout
