"""The command line's and the sweeps' paths through Hydra, as the README's commands take them, in
processes of their own: ``--version``, ``--help``, an experiment's sweep (``-m experiment=...``)
on the default launcher, a sweep's config without ``-m``, a tuning study run twice on one Optuna
storage, one stopped (Ctrl-C, a kill) and continued, a run stopped and resumed, and
``zrp-ga-report`` on them. Marked ``hydra_cli``: CI runs these under the newest hydra-core pre-release as well (``.ci/smoke_hydra.sh``). No Hydra or
OmegaConf warning may be printed (hydra-core 1.4 warns of what 1.5 will refuse)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import pytest

pytestmark = pytest.mark.hydra_cli
BIN = Path(sys.executable).parent


def zrp_ga(*args: str, cwd: Path, check: bool = True) -> subprocess.CompletedProcess:
    out = subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args], capture_output=True, text=True, cwd=cwd)
    if check:
        assert out.returncode == 0, out.stderr[-2000:]
        quiet(out.stderr)
    return out


def quiet(stderr: str) -> None:
    """No warning of Python's (Hydra's deprecations, OmegaConf's) and no traceback on stderr."""
    lines = [line for line in stderr.splitlines() if "Warning" in line or "Traceback" in line]
    assert not lines, "\n".join(lines)


def test_version_is_zrp_gas(tmp_path):
    out = zrp_ga("--version", cwd=tmp_path)
    assert out.stdout.split()[:2] == ["zrp_ga", metadata.version("zrp_ga")]
    assert f"hydra-core {metadata.version('hydra-core')}" in out.stdout


def test_help_lists_the_groups_and_quoted_examples(tmp_path):
    out = zrp_ga("--help", cwd=tmp_path)
    assert "crossover: blend" in out.stdout and "zrp-ga -m crossover=blend,sbx 'seed=range(5)'" in out.stdout


HYDRAS_OWN_HELP = "import sys; sys.argv = ['zrp-ga', *sys.argv[1:]]; from zrp_ga.cli.main import main; main()"


@pytest.mark.parametrize("args", [["problem=multipose", "--help"],  # an override: the config it composes
                                  ["-h", "hydra.help.template='$HYDRA_CONFIG_GROUPS|${hydra.job.name}|$CONFIG'"]])  # fmt: skip
def test_help_is_hydras_own_text(tmp_path, args):
    """zrp-ga prints --help from one composition and one listing of the groups (zrp_ga.cli.main._help):
    the same text as Hydra's own --help (main() without cli()), Hydra's groups and the config
    (``$HYDRA_CONFIG_GROUPS``, ``$CONFIG``, an interpolation) included."""
    ours = zrp_ga(*args, cwd=tmp_path)
    hydras = subprocess.run([sys.executable, "-c", HYDRAS_OWN_HELP, *args], capture_output=True, text=True, cwd=tmp_path)
    assert hydras.returncode == 0, hydras.stderr[-2000:]
    assert ours.stdout == hydras.stdout
    if "-h" in args:
        assert "hydra/launcher: basic, " in ours.stdout and "|zrp-ga|" in ours.stdout and "crossover:\n" in ours.stdout
    else:
        assert "crossover: blend, none, " in ours.stdout


@pytest.mark.slow  # 4-12 s: out of the default run for its time (pytest -m slow runs it)
def test_help_is_left_to_hydra_where_zrp_ga_cannot_print_it(tmp_path):
    """Hydra's own --help answers another flag (a user's --config-dir), a template wanting Hydra's
    parser ($FLAGS_HELP) and a config that does not compose (its one-line error, exit code 2)."""
    from zrp_ga.cli.main import _help

    for args in (["--help", "--config-dir", str(tmp_path)], ["--help", "--cfg", "job"], ["--help", "hydra.help.template=$FLAGS_HELP"],
                 ["--help", "crossover=nope"], ["problem=multipose"]):  # fmt: skip
        assert _help(args) is False, args
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "myarm.yaml").write_text("name: ur10\n")
    out = zrp_ga("--help", "--config-dir", str(tmp_path), cwd=tmp_path)
    assert "robot: file, myarm, puma560, stanford, ur10" in out.stdout
    flags = zrp_ga("--help", "hydra.help.template=$FLAGS_HELP", cwd=tmp_path)
    assert "--config-dir" in flags.stdout
    bad = zrp_ga("--help", "crossover=nope", cwd=tmp_path, check=False)
    assert bad.returncode == 2 and bad.stderr.startswith("zrp-ga: error: ") and "crossover" in bad.stderr


# the sweeper's params as quoted strings (a comma or range() unquoted would be a sweep over Hydra's own config)
SMALL_GRID = ["population.max_evals=100", "hydra.sweeper.params.crossover='blend,sbx'", "hydra.sweeper.params.mutation=gaussian",
              "hydra.sweeper.params.inversion=none", "hydra.sweeper.params.rotation=none", "hydra.sweeper.params.seed='range(2)'"]  # fmt: skip


@pytest.mark.slow  # 10-30 s: kept out of the default run (under ten minutes); pytest -m slow
def test_an_experiment_sweeps_with_m_on_zrp_gas_launcher(tmp_path):
    """``zrp-ga -m experiment=operator_grid`` (the grid made small): every job done, on zrp_ga's
    launcher (the default); the same without ``-m``: run as a sweep (hydra-core 1.3, from the
    config's ``hydra.mode``) or refused on one line saying to add ``-m`` (1.4)."""
    import yaml

    zrp_ga("-m", "experiment=operator_grid", *SMALL_GRID, "hydra.sweep.dir=grid", cwd=tmp_path)
    manifest = (tmp_path / "grid" / "manifest.csv").read_text()
    assert manifest.count(",done,") == 4, manifest
    hydra = yaml.safe_load((tmp_path / "grid" / "0" / ".hydra" / "hydra.yaml").read_text())["hydra"]
    assert hydra["launcher"]["_target_"] == "hydra_plugins.zrp_ga_launcher.launcher.ZrpGaLauncher"
    assert hydra["runtime"]["choices"]["hydra/launcher"] == "local"
    out = zrp_ga("experiment=operator_grid", *SMALL_GRID, "hydra.sweep.dir=grid2", cwd=tmp_path, check=False)
    if out.returncode == 0:  # hydra-core 1.3
        assert (tmp_path / "grid2" / "manifest.csv").read_text().count(",done,") == 4
    else:
        assert out.returncode == 2 and "zrp-ga -m experiment=" in out.stderr.splitlines()[-1], out.stderr


@pytest.mark.slow  # 17 s; test_a_tuning_study_stopped_settles_its_trials_and_continues continues a study too (slow)
def test_a_tuning_study_continues_without_repeating_a_trial(tmp_path):
    """``zrp-ga -m hparams_search=ga_optuna`` twice on one sweep folder: the study in its
    ``optuna.db`` holds both runs' trials (3 + 3), each with its own settings, folder and seed;
    ``zrp-ga-report`` names the best trial and the parameters' importance."""
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper", reason="the tune extra: pip install '.[tune]'")
    import optuna

    tune = ["-m", "hparams_search=ga_optuna", "hydra.sweeper.n_trials=3", "population.max_evals=1000", "hydra.sweep.dir=tune"]
    for _ in range(2):
        zrp_ga(*tune, cwd=tmp_path)
    sweep = tmp_path / "tune"
    study = optuna.load_study(study_name="zrp_ga_pure_ga", storage=f"sqlite:///{sweep / 'optuna.db'}")
    trials = study.get_trials()
    assert [t.state.name for t in trials] == ["COMPLETE"] * 6
    assert len({tuple(sorted(t.params.items())) for t in trials}) == 6  # no trial proposed twice
    seeds = [json.loads((sweep / str(k) / "summary.json").read_text())["seed"] for k in range(6)]
    assert seeds == list(range(6))  # a folder and a seed per trial, numbered in the study
    report = subprocess.run([str(BIN / "zrp-ga-report"), str(sweep), "--out", str(tmp_path / "report")], capture_output=True, text=True)
    assert report.returncode == 0, report.stderr[-2000:]
    tuning = (tmp_path / "report" / "tuning.md").read_text()
    assert "6 trials" in tuning and f"{study.best_value:.6g}" in tuning
    for name in study.best_params:
        assert name in tuning


@pytest.mark.slow
@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGKILL], ids=["ctrl_c", "killed"])
def test_a_tuning_study_stopped_settles_its_trials_and_continues(tmp_path, stop):
    """``zrp-ga -m hparams_search=ga_optuna`` stopped (its process group signalled) while a
    trial's run has finished and another runs. Ctrl-C: no trial stays RUNNING in ``optuna.db``,
    a finished one holds the objective in its folder's ``summary.json``, the others FAIL.
    Killed (no handler runs): the trials stay RUNNING until the same command continues the study,
    which settles them so; either way it adds new trials, none of them repeating settings."""
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper", reason="the tune extra: pip install '.[tune]'")
    import optuna

    tune = ["-m", "hparams_search=ga_optuna", "hydra.sweeper.n_trials=4", "population.max_evals=4000", "hydra.sweep.dir=tune"]
    sweep = tmp_path / "tune"
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *tune], cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip

    def states() -> dict[str, str]:
        found = {}
        for f in sweep.glob("*/status.json"):
            try:
                found[f.parent.name] = json.loads(f.read_text())["status"]
            except (OSError, ValueError, KeyError):
                pass
        return found

    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        now = states()
        if "done" in now.values() and "running" in now.values():
            break
        time.sleep(0.05)
    if proc.poll() is None:
        os.killpg(proc.pid, stop)
    try:
        _, stderr = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise
    if proc.returncode == 0:
        pytest.skip("the sweep ended before it was stopped (a fast machine)")
    url = f"sqlite:///{sweep / 'optuna.db'}"
    trials = optuna.load_study(study_name="zrp_ga_pure_ga", storage=url).get_trials()
    done = {int(k) for k, v in states().items() if v == "done"}
    assert done and trials  # the trial that had finished when the sweep was stopped

    def settled(trials: list) -> None:
        for t in trials:
            if t.number in done:
                summary = json.loads((sweep / str(t.number) / "summary.json").read_text())
                assert (t.state.name, t.value) == ("COMPLETE", summary["objective"])
                assert summary["seed"] == t.number  # the trial's own folder
            else:
                assert t.state.name == "FAIL"

    if stop == signal.SIGINT:
        assert proc.returncode == 130
        assert "not continued" in stderr and "new trials" in stderr, stderr[-2000:]
        settled(trials)
    else:
        assert "RUNNING" in [t.state.name for t in trials]  # what the continued run has to settle

    zrp_ga(*tune[:2], "hydra.sweeper.n_trials=2", *tune[3:], cwd=tmp_path)
    again = optuna.load_study(study_name="zrp_ga_pure_ga", storage=url).get_trials()
    assert len(again) == len(trials) + 2
    assert [t.state.name for t in again[len(trials) :]] == ["COMPLETE"] * 2
    settled(again[: len(trials)])
    assert len({tuple(sorted(t.params.items())) for t in again}) == len(again)  # no settings proposed twice


@pytest.mark.slow  # 10-30 s: kept out of the default run (under ten minutes); pytest -m slow
def test_a_run_stopped_and_resumed_from_the_command_line(tmp_path):
    """A GA run stopped by SIGTERM (as a cluster's time limit stops it), then ``zrp-ga
    resume=DIR``: the run ends with its whole convergence.csv."""
    args = ["problem=multipose", "problem.n_poses=6", "problem.n_validation=5", "population.generations=3000", "checkpoint_every=5",
            "progress=false", "hydra.run.dir=cut"]  # fmt: skip
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *args], cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)  # fmt: skip
    curve = tmp_path / "cut" / "convergence.csv"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if curve.exists() and curve.read_text().count("\n") > 30:
            break
        time.sleep(0.1)
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
    proc.wait(120)
    if "interrupted" not in (tmp_path / "cut" / "status.json").read_text():
        pytest.skip("the run ended before it was stopped (a fast machine)")
    zrp_ga("resume=cut", "progress=false", cwd=tmp_path)
    assert '"done"' in (tmp_path / "cut" / "status.json").read_text()
    assert curve.read_text().count("\n") == 3002
