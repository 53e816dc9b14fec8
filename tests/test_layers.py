"""The layers of the README's Layout section hold: import-linter's contracts in pyproject.toml
(each layer imports only the layers below it; the model's modules from the bottom up; the public
modules above the files they re-export; no Hydra or OmegaConf below the entry points, not even
through another module), checked on the code as it is, and each contract shown to bite: one
violation planted per contract in a copy of the package, reported as that contract broken (the
others kept), naming the offending import."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))
CONTRACTS = [c["name"] for c in tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]]


def lint(root: Path) -> subprocess.CompletedProcess:
    if not Path(LINT).exists():
        pytest.fail("lint-imports is missing: pip install -e '.[test]'")
    return subprocess.run([LINT, "--no-cache"], cwd=root, capture_output=True, text=True, timeout=300,
                          env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"})  # fmt: skip


def test_the_layers_hold():
    done = lint(ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"Contracts: {len(CONTRACTS)} kept, 0 broken." in done.stdout


# contract -> (module, the line planted at its end, the offending import(s) as lint-imports names them)
PLANTS = {
    "zrp_ga's layers": ("zrp_ga/model/kinematics.py", "import zrp_ga.algorithms.ga",
                        ["zrp_ga.model.kinematics -> zrp_ga.algorithms.ga (l.{n})"]),
    "the model, from the bottom up": ("zrp_ga/model/so3.py", "from zrp_ga.model import robot",
                                      ["zrp_ga.model.so3 -> zrp_ga.model.robot (l.{n})"]),
    "the public modules re-export the model and the presets": ("zrp_ga/io/presets.py", "import zrp_ga.robots",
                                                               ["zrp_ga.io.presets -> zrp_ga.robots (l.{n})"]),
    # indirect: the run layer imports a helper module (outside every layer) that imports Hydra
    "no Hydra or OmegaConf below the entry points and zrp_ga.config, not even indirectly": (
        "zrp_ga/run/build.py", "from zrp_ga import hydra_helper",
        ["zrp_ga.run.build -> zrp_ga.hydra_helper (l.{n})", "zrp_ga.hydra_helper -> hydra (l.2)"]),
}  # fmt: skip


def test_every_contract_has_a_plant():
    assert sorted(PLANTS) == sorted(CONTRACTS)


@pytest.mark.parametrize("contract", list(PLANTS))
def test_a_planted_violation_breaks_its_contract_alone(tmp_path, contract):
    copy = tmp_path / "repo"
    shutil.copytree(ROOT, copy, ignore=shutil.ignore_patterns(".git", ".venv*", "outputs", "multirun", "__pycache__", "experiments", "tests"))
    (copy / "zrp_ga" / "hydra_helper.py").write_text('"""A helper that imports Hydra."""\nimport hydra  # noqa: F401\n')
    module, line, offending = PLANTS[contract]
    path = copy / module
    path.write_text(path.read_text() + f"\n{line}  # planted\n")
    n = len(path.read_text().splitlines())
    done = lint(copy)
    assert done.returncode != 0
    report = " ".join(done.stdout.split())  # long contract names are wrapped
    for name in CONTRACTS:
        assert f"{name} {'BROKEN' if name == contract else 'KEPT'}" in report, name
    lines = [x.strip().lstrip("- ").strip() for x in done.stdout.splitlines()]
    for imported in offending:
        assert imported.format(n=n) in lines, done.stdout
