#!/usr/bin/env bash
# CI: zrp-ga under the newest pre-release of hydra-core (1.4 today), in a venv of its own: the tests
# marked hydra_cli (every command of the README and --help parsed; --version, --help, an experiment
# with -m, a tuning study continued, resume, the report), then --help, --cfg job, a default run, a
# short sweep with each launcher (zrp_ga's, joblib), a sweep killed and continued by the same
# command, a run interrupted and resumed. A few minutes.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv-hydra-pre
fail() { echo "smoke: $*" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
rm -rf "$venv"
python3 -m venv "$venv"
. "$venv/bin/activate"
python -m pip install --upgrade pip >/dev/null
pip install ".[test,joblib,tune]" >/dev/null
# hydra-core's newest release within the pin, pre-releases included (and what it needs of them:
# OmegaConf's, Optuna's sweeper's); every other package as a user gets it.
pip install --pre --upgrade "hydra-core<1.5" "hydra-optuna-sweeper<1.5" >/dev/null
echo "smoke: hydra-core $(python -c 'import hydra; print(hydra.__version__)'), omegaconf $(python -c 'import omegaconf; print(omegaconf.__version__)')"
# the installed package (not the source tree: --import-mode=importlib puts no folder on the path)
pytest -q -m hydra_cli -p no:cacheprovider tests || fail "the hydra_cli tests failed under the pre-release"
cd "$work"
# Hydra's deprecation and policy warnings on stderr would mean zrp_ga uses something on its way out.
quiet() { ! grep -E "Warning|Traceback" "$1" >&2 || fail "$2 printed warnings (above)"; }

zrp-ga --help > help.txt 2> err.txt || fail "--help failed"
grep -q "Option groups" help.txt && grep -q "crossover: blend" help.txt || fail "--help lists no option groups"
quiet err.txt "--help"
zrp-ga --cfg job > job.yaml 2> err.txt || fail "--cfg job failed"
grep -q "^algorithm:" job.yaml || fail "--cfg job printed no config"
quiet err.txt "--cfg job"

zrp-ga hydra.run.dir=run progress=false > out.txt 2> err.txt || fail "a default run failed: $(tail -3 err.txt)"
grep -q "the paper: 0.241" out.txt && [ -f run/summary.json ] && [ -f run/calibrated_robot.urdf ] || fail "a default run wrote no results"
quiet err.txt "a default run"

small=(problem=multipose problem.n_poses=6 problem.n_validation=5 population.generations=3 seed=0,1 crossover=blend,sbx)
for launcher in local joblib; do
  zrp-ga -m "${small[@]}" hydra/launcher=$launcher hydra.launcher.n_jobs=2 hydra.sweep.dir=sweep-$launcher > /dev/null 2> err.txt \
    || fail "a sweep on hydra/launcher=$launcher failed: $(tail -3 err.txt)"
  [ "$(grep -c ',done,' sweep-$launcher/manifest.csv)" = 4 ] || fail "hydra/launcher=$launcher: not every job done"
done

long=(-m problem=multipose problem.n_poses=6 problem.n_validation=5 population.generations=400 checkpoint_every=5
      seed=0,1,2,3 hydra/launcher=local hydra.launcher.n_jobs=2 hydra.sweep.dir=killed)
setsid zrp-ga "${long[@]}" > /dev/null 2>&1 &
pid=$!
for _ in $(seq 1200); do
  [ "$(cat killed/*/convergence.csv 2>/dev/null | wc -l)" -gt 200 ] && break
  sleep 0.1
done
kill -KILL -- -"$pid" 2>/dev/null || true
wait "$pid" 2>/dev/null || true
zrp-ga "${long[@]}" > /dev/null 2> err.txt || fail "a killed sweep did not continue: $(tail -3 err.txt)"
[ "$(grep -c ',done,' killed/manifest.csv)" = 4 ] || fail "the continued sweep did not finish every job"
for job in 0 1 2 3; do
  [ "$(wc -l < killed/$job/convergence.csv)" = 402 ] || fail "killed/$job/convergence.csv is not whole after continuing"
done

zrp-ga problem=multipose problem.n_poses=6 problem.n_validation=5 population.generations=1500 checkpoint_every=5 \
  progress=false hydra.run.dir=cut > /dev/null 2>&1 &
pid=$!
for _ in $(seq 1200); do
  [ "$(cat cut/convergence.csv 2>/dev/null | wc -l)" -gt 50 ] && break
  sleep 0.1
done
kill -TERM "$pid"  # as a cluster's job limit stops it (a background job of a script ignores SIGINT)
wait "$pid" && fail "the interrupted run did not stop" || true
grep -q interrupted cut/status.json || fail "the interrupted run's status.json does not say so"
zrp-ga resume=cut progress=false > out.txt 2> err.txt || fail "resume failed: $(tail -3 err.txt)"
grep -q '"done"' cut/status.json && [ "$(wc -l < cut/convergence.csv)" = 1502 ] || fail "the resumed run did not finish"
grep -q "the paper" out.txt && fail "the resumed run prints the paper's line" || true
echo "smoke: hydra-core pre-release: --help, --cfg job, a run, sweeps (zrp_ga, joblib), a killed sweep continued, resume: ok"
