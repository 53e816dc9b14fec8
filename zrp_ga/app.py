"""``zrp-ga``: the Hydra app. ``zrp-ga`` alone runs the paper's case study; any setting can be
overridden (``zrp-ga problem=multipose seed=3``) or swept (``zrp-ga -m crossover=glob(*)``).

:func:`run` is the typed, testable body; :func:`main` is the thin Hydra entry point and
:func:`cli` the console script, which turns every configuration error into one line.
"""

from __future__ import annotations

import logging
import os
import pickle
import random
import sys
import time
from pathlib import Path

import hydra
import numpy as np
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from zrp_ga import baselines, build, config, ga, records

log = logging.getLogger("zrp_ga")
CHECKPOINT = "checkpoint.pkl"
config.register()


class Progress:
    """A progress line: generation, evaluations, best cost and time left, at most twice a second
    (rewritten in place on a terminal)."""

    def __init__(self, generations: int | None, max_evals: int | None, stream=sys.stderr):
        self.generations, self.max_evals, self.stream = generations, max_evals, stream
        self.tty = stream.isatty()
        self._last = 0.0

    def __call__(self, row: dict, final: bool = False) -> None:
        now = time.perf_counter()
        if not final and now - self._last < 0.5:
            return
        self._last = now
        done = max(row["gen"] / self.generations if self.generations else 0.0,
                   row["nevals"] / self.max_evals if self.max_evals else 0.0)  # fmt: skip
        left = row["wall_s"] * (1 - done) / done if 0 < done <= 1 else None
        text = (f"gen {row['gen']:5d}  evals {row['nevals']:8d}  best {row['best']:.6g}  "
                f"val_rms {row.get('val_rms', float('nan')):.4g} mm")  # fmt: skip
        if left is not None:
            text += f"  time left {left:6.1f} s"
        if self.tty:
            self.stream.write("\r" + text + ("\n" if final else ""))
        else:
            self.stream.write(text + "\n")
        self.stream.flush()


def _save(path: Path, state: dict) -> None:
    """Write a checkpoint atomically: a kill while writing leaves the previous one."""
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        pickle.dump(state, f, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)


def run(cfg: DictConfig, out_dir: str | Path, progress: Progress | None = None) -> dict:
    """Run one calibration as configured, write its files into ``out_dir``, return the summary.

    With ``cfg.resume`` set, the run in that directory continues from its checkpoint, with the
    config it was started with. A directory that already holds a run is never overwritten.
    """
    state = None
    if cfg.get("resume"):
        out = Path(cfg.resume).expanduser()
        if not (out / CHECKPOINT).exists():
            raise build.ConfigError(f"resume: no {CHECKPOINT} in {out}")
        with open(out / CHECKPOINT, "rb") as f:
            state = pickle.load(f)
        cfg = OmegaConf.create(state["config"])
        log.info("continuing %s after generation %d", out, state["gen"])
    else:
        out = Path(out_dir)
        if (out / "convergence.csv").exists():
            raise build.ConfigError(
                f"output directory {out} already holds a run (convergence.csv); "
                f"choose another hydra.run.dir, or continue it with resume={out}"
            )
    out.mkdir(parents=True, exist_ok=True)
    seed = int(cfg.seed)
    random.seed(seed)  # DEAP's own code draws from `random`
    np.random.seed(seed % 2**32)
    rng = np.random.default_rng([seed, 0])  # the optimiser's stream; the problem draws from [seed, 1]
    name = cfg.algorithm.name
    if name not in ("ga", "lm", "cmaes"):
        raise build.ConfigError(f"algorithm.name: unknown algorithm {name!r}; known: ga, lm, cmaes")
    if cfg.get("checkpoint_every", 0) < 0:
        raise build.ConfigError(f"checkpoint_every: must be >= 0, got {cfg.checkpoint_every}")
    arm = build.robot(cfg.robot, cfg.problem.get("robot"))
    problem, extra = build.problem(cfg.problem, arm, seed)
    settings = build.settings(cfg) if name == "ga" else None
    toolbox = build.toolbox(cfg, problem, rng) if name == "ga" else None
    report, model_rank = problem.identifiability(), problem.model_rank()
    if report.rank < model_rank and state is None:
        log.warning(
            "the calibration data cannot identify every parameter the model can (rank %d of %d; "
            "more poses would help):\n%s", report.rank, model_rank, report,
        )  # fmt: skip
    zero = np.zeros((1, problem.layout.size))
    nominal_cost = float(problem.costs(zero)[0])
    val_before = [float(v[0]) for v in problem.validation_error(zero)]
    records.write_json(out / "status.json", {"status": "running"})

    t_start = time.perf_counter()
    resume_at = state["gen"] if state is not None else None
    last_row: dict = {}
    resolved = OmegaConf.to_container(cfg, resolve=True)
    with records.ConvergenceLog(out / "convergence.csv", keep_until_gen=resume_at) as conv:
        if state is not None:
            state["logbook"] = conv.logbook()

        def on_generation(row: dict, best: np.ndarray, best_cost: float) -> None:
            rms, vmax = problem.validation_error(best)
            row.update(val_rms=rms[0], val_max=vmax[0], param_err=problem.param_error(best)[0])
            conv.write(row)
            last_row.update(row)
            log.debug("gen %d evals %d best %.6g val_rms %.4g mm", row["gen"], row["nevals"], row["best"], rms[0])
            if progress is not None:
                progress(row)

        def checkpoint(ga_state: dict) -> None:
            # Without the logbook: convergence.csv is the log, and pickling the whole logbook at
            # every checkpoint made long runs quadratic (3000 generations: 5.6 s -> 17.5 s).
            state = {k: v for k, v in ga_state.items() if k != "logbook"}
            _save(out / CHECKPOINT, {**state, "config": resolved})

        if name == "ga":
            every = int(cfg.get("checkpoint_every", 0))
            try:
                result = ga.evolve(problem, toolbox, settings, rng, on_generation, checkpoint, every, state)
            except BaseException as exc:  # Ctrl-C or a crash: say so where the report will look
                status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
                records.write_json(out / "status.json", {"status": status, "error": repr(exc)})
                raise
        elif state is not None:
            raise build.ConfigError("resume: only GA runs keep checkpoints")
        elif name == "lm":
            result = baselines.lm(problem, cfg.algorithm.get("max_evals"), on_generation)
        else:
            result = baselines.cmaes(
                problem, cfg.population.lambda_, rng, cfg.population.generations, cfg.population.max_evals,
                cfg.algorithm.sigma0, on_generation,
            )  # fmt: skip
    wall = time.perf_counter() - t_start + (state["wall_s"] if state is not None else 0.0)
    if progress is not None and last_row:
        progress({**last_row, "wall_s": wall}, final=True)

    truth = problem.true_de
    if problem.cost == "nonlinear":  # the linear cost has no exact null directions to remove
        result.best = problem.canonical(result.best)
        truth = None if truth is None else problem.canonical(truth)
    records.params_by_joint(problem, result.best, truth).to_csv(out / "best_params.csv", index=False)
    records.population_table(problem, result.initial_genes, result.initial_costs).to_csv(
        out / "initial_population.csv", index=False
    )
    initial_best = float(np.nanmin(np.where(np.isfinite(result.initial_costs), result.initial_costs, np.nan)))
    val_after = [float(v[0]) for v in problem.validation_error(result.best)]
    summary = {
        "algorithm": name,
        "seed": seed,
        "final_cost": result.best_cost,
        "initial_cost": initial_best,
        "nominal_cost": nominal_cost,
        "final_over_initial": result.best_cost / initial_best,
        "nevals": result.nevals,
        "stop_reason": result.stop_reason,
        "wall_s": wall,
        "validation_rms_mm": {"nominal": val_before[0], "calibrated": val_after[0]},
        "validation_max_mm": {"nominal": val_before[1], "calibrated": val_after[1]},
        "param_err": {"nominal": float(problem.param_error(zero)[0]), "calibrated": float(problem.param_error(result.best)[0])},
        "identifiability": {"rank": report.rank, "model_rank": model_rank, "n_params": report.n_params,
                            "condition_number": report.condition_number, "unidentifiable": report.null_directions},
        "best_genome": dict(zip(problem.layout.names, result.best.tolist())),
        "config": resolved,
        "versions": records.versions(),
    }  # fmt: skip
    if isinstance(extra, build.Measured):
        summary.update(measured_outputs(problem, extra, result.best, out))
    records.write_json(out / "summary.json", summary)
    records.write_json(out / "status.json", {"status": "done"})
    return summary


def measured_outputs(problem, measured: build.Measured, best: np.ndarray, out: Path) -> dict:
    """For measured data: the registration, the calibrated model in the instrument's frame (a
    ZRPRobot YAML that ``from_yaml`` and ``forward`` load back), per-pose errors and their plot."""
    from zrp_ga import report  # matplotlib only where it is needed

    records.write_json(out / "registration.json", measured.registration.to_dict())
    robot = problem.layout.robot(problem.nominal, best, name=f"{problem.nominal.name} calibrated")
    robot.to_yaml(out / "calibrated_robot.yaml")
    sets = {"calibration": problem.calibration}
    if problem.validation is not None:
        sets["validation"] = problem.validation
    errors = {k: (problem.position_errors(np.zeros_like(best), m), problem.position_errors(best, m)) for k, m in sets.items()}
    report.plot_pose_errors(errors, out)

    def stats(e: np.ndarray) -> dict:
        return {"mean": float(e.mean()), "rms": float(np.sqrt(np.mean(e**2))), "max": float(e.max()), "poses": len(e)}

    return {
        "registration": measured.registration.to_dict(),
        "position_error_mm": {k: {"nominal": stats(b), "calibrated": stats(a)} for k, (b, a) in errors.items()},
        "files": {"calibration": measured.calibration.source,
                  "validation": measured.validation.source if measured.validation is not None else None},
    }  # fmt: skip


@hydra.main(version_base="1.3", config_path="pkg://zrp_ga.conf", config_name="config")
def main(cfg: DictConfig) -> None:
    hc = HydraConfig.get()
    out = hc.runtime.output_dir
    multirun = hc.mode == RunMode.MULTIRUN
    budget = (cfg.population.generations, cfg.population.max_evals) if cfg.algorithm.name != "lm" else (None, None)
    progress = Progress(*budget) if cfg.progress and not multirun else None
    try:
        s = run(cfg, out, progress)
    except KeyboardInterrupt:
        where = cfg.resume or out
        print(f"\nzrp-ga: interrupted; the checkpoint and convergence.csv in {where} are complete up to "
              f"the last finished generation: continue with  zrp-ga resume={where}", file=sys.stderr)  # fmt: skip
        sys.exit(130)
    except ValueError as exc:  # ConfigError and bad input files: one line, no traceback
        if multirun:
            raise  # recorded as this job's failure in the sweep manifest; the other jobs go on
        print(f"zrp-ga: error: {exc}", file=sys.stderr)
        sys.exit(2)
    if multirun:
        v = s["validation_rms_mm"]["calibrated"]
        log.info("job %s [%s]: best %.6g after %d evaluations, validation %.4g mm, %.1f s",
                 hc.job.num, " ".join(hc.overrides.task), s["final_cost"], s["nevals"], v, s["wall_s"])  # fmt: skip
        return
    print(f"results in {out if not cfg.resume else cfg.resume}")
    print(
        f"cost {s['initial_cost']:.4g} -> {s['final_cost']:.4g} after {s['nevals']} evaluations: "
        f"final/initial = {s['final_over_initial']:.3g} (the paper: 0.241 after 11 iterations)"
    )
    v = s["validation_rms_mm"]
    print(f"validation RMS position error on unseen poses: {v['nominal']:.4g} mm nominal -> {v['calibrated']:.4g} mm calibrated")


def cli() -> None:
    """The console script: composition errors (a typo in a key, a wrong type, an unknown option)
    become one line naming the key, before Hydra starts; then :func:`main` runs."""
    args = sys.argv[1:]
    single = not any(a in ("-m", "--multirun") or a.startswith("hydra.mode") for a in args)
    plain = [a for a in args if not a.startswith("-") and not a.lstrip("+~").startswith("hydra")]
    if single:
        try:
            config.load(plain)
        except Exception as exc:  # Hydra and OmegaConf errors: keep what names the key
            print(f"zrp-ga: error: {one_line(exc)}", file=sys.stderr)
            sys.exit(2)
    main()


def one_line(exc: BaseException) -> str:
    """A composition error on one line: what is wrong and the key (or the options) it concerns."""
    for e in (exc.__cause__, exc):
        lines = [line.strip() for line in str(e or "").splitlines() if line.strip()]
        key = next((line.split(":", 1)[1].strip() for line in lines if line.startswith("full_key:")), None)
        if key:
            return f"{lines[0]} (key: {key})"
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()] or [type(exc).__name__]
    heads = [k for k, line in enumerate(lines) if line.startswith("Available options in")]
    if heads:
        options = [line for line in lines[heads[0] + 1 :] if not line.startswith(("Config search path", "provider="))]
        return f"{lines[0]}; {lines[heads[0]].rstrip(':').lower()}: {', '.join(options)}"
    return lines[0]


if __name__ == "__main__":
    cli()
