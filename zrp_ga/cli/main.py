"""``zrp-ga``: Hydra's app. ``zrp-ga`` alone runs the
paper's case study; any setting can be overridden (``zrp-ga problem=multipose seed=3``), swept
(``zrp-ga -m crossover=glob(*)``) or inspected with Hydra's own flags (``--cfg job``,
``--info defaults``, ``--help``).

:func:`main` is the ``@hydra.main`` entry point: it reads what Hydra knows about the run (its
directory, the command line's overrides, the groups' options, the sweep job) and hands the
config, typed (:func:`zrp_ga.config.typed`), to the run layer (:mod:`zrp_ga.run`), which
checks, runs and records it (a single run
was checked and built before Hydra made its directory, by the ``Prepare`` callback of
:mod:`zrp_ga.cli.callbacks`, and is run as built). :func:`cli` is the console script, which
turns every error in the user's input into one line and exit code 2. Heavy modules are
imported where they are used, so that ``--help`` starts fast.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import hydra
from omegaconf import DictConfig

import hydra_plugins.zrp_ga_sweeper.sweeper  # noqa: F401  hydra/sweeper=zrp_ga stored, also where main() is called without cli()
from zrp_ga import config
from zrp_ga.core.errors import one_line

config.launcher_stored()  # conf/config.yaml's default launcher, also where main() is called without cli()
# hydra.main's keyword of 1.4 alone (the hydra-core installed may be 1.3, whose hydra.main has no such keyword)
_HYDRA_14_OPTIONS: dict[str, Any] = {"execution_whitelist": config.TRUSTED_TARGETS} if config.hydra_14() else {}


@hydra.main(config_path="pkg://zrp_ga.conf", config_name="config", **config.hydra_options(), **_HYDRA_14_OPTIONS)
def main(cfg: DictConfig) -> float:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from zrp_ga.cli.callbacks import take_prepared
    from zrp_ga.run import build, execute, summary
    from zrp_ga.run.directory import Sweep
    from zrp_ga.run.sweep import SweepJob, sweep_job

    hc = HydraConfig.get()
    out = Path(hc.runtime.output_dir)
    choices = dict(hc.runtime.choices)
    overrides = list(hc.overrides.task)
    if hc.mode == RunMode.MULTIRUN:
        sweep = Sweep(Path(hc.sweep.dir), int(hc.job.num), tuple(overrides), str(hc.sweep.subdir))
        objective = sweep_job(SweepJob(config.typed(cfg), out, sweep, choices))
        summary.console(out, (hc.job.num, " ".join(overrides)))
    else:
        p = take_prepared(out) or build.prepare(config.typed(cfg), out, overrides, choices)  # built once, by Prepare
        objective = execute.objective(execute.run_prepared(p, bool(cfg.progress)))  # the command line's (resume keeps it)
        assert p.out is not None  # the command line's run has its directory: Hydra's, or the resumed run's
        summary.console(p.out)
    return objective


def warm_up(cfg: DictConfig) -> None:
    """zrp_ga's launcher's warm-up (``hydra.launcher.warm_up``) of a sweep of :func:`main`: the
    run layer's (:func:`zrp_ga.run.execute.warm_up`) on the sweep's config, typed; a config that
    cannot be typed fails again, with its message, in the jobs themselves."""
    from zrp_ga.run import execute

    try:
        typed = config.typed(cfg)
    except Exception:
        return
    execute.warm_up(typed)


def cli() -> None:
    """The console script: :func:`main`, with the errors in the user's input (a bad key or value,
    a missing or malformed file) printed as one line, exit code 2, and Ctrl-C (or SIGTERM, as a
    cluster's job limit sends it) as a hint to resume.

    Hydra prints composition errors over several lines and exits with 1; with
    ``HYDRA_FULL_ERROR`` set it raises them instead, which is how they are caught here (set it
    yourself to see Hydra's full traceback)."""
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from zrp_ga.cli.callbacks import Refused

    if "--version" in sys.argv[1:]:  # zrp_ga's (Hydra's own flag would print hydra-core's only)
        print(version())
        return
    full = os.environ.get("HYDRA_FULL_ERROR") == "1"
    os.environ["HYDRA_FULL_ERROR"] = "1"
    signal.signal(signal.SIGTERM, _stop)  # a job limit or shutdown: stop as at Ctrl-C, checkpoints saved
    # A log file that cannot be written (a full disk) loses its line without the logging module's
    # traceback on stderr: the run's own error names the file (and the console has the line).
    logging.raiseExceptions = False
    _register_launcher()
    held = _JobLineHeld(sys.stderr)
    try:
        with _few_collections(), contextlib.redirect_stderr(held):
            if not _help(sys.argv[1:]):
                main()
    except BrokenPipeError:  # stdout closed early (`zrp-ga --help | head`): quiet, as Python's docs advise (signal, "Note on SIGPIPE")
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing more written at exit
        sys.exit(1)
    except (HydraException, OmegaConfBaseException, ValueError, OSError, MemoryError, Refused) as exc:
        if full:
            held.release()
            raise
        print(f"zrp-ga: error: {_hint(one_line(getattr(exc, 'error', exc)))}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        from zrp_ga.cli import study

        print(f"\nzrp-ga: interrupted; {_continue_with(study.interrupted())}", file=sys.stderr)  # a tuning sweep's trials settled
        sys.exit(130)
    except BaseException:
        held.release()
        raise


class _JobLineHeld:
    """``sys.stderr`` with Hydra's line ``Error executing job with overrides: [...]`` (written
    by ``JobReturn.return_value`` just before it raises a job's error, in a single run and in
    a sweep) held back: :func:`cli`'s own line names what failed (a full disk: the file), so it
    is the only line; written out (:meth:`release`) before any other error's traceback."""

    PREFIX = "Error executing job with overrides: "

    def __init__(self, stream: Any) -> None:
        self.stream = stream
        self.held: list[str] = []

    def write(self, text: str) -> int:
        if text.startswith(self.PREFIX):
            self.held.append(text)
            return len(text)
        return self.stream.write(text)

    def release(self) -> None:
        self.stream.writelines(self.held)
        self.held.clear()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


def _help(args: list[str]) -> bool:
    """``zrp-ga --help [OVERRIDES]``: Hydra's help text, printed from one composition and one
    listing of the config groups through Hydra's public interfaces (the Compose API, the config
    loader's sources, :class:`~hydra.plugins.config_source.ConfigSource`), instead of Hydra's
    ``--help``, which deep-copies its config repository (Hydra's and zrp_ga's structured configs in
    its ConfigStore) for each of about 120 questions about the groups: 2 CPU-s for 0.5.

    False, and Hydra answers, for any other command line (another flag, ``--config-dir``: the
    search path is not the package's alone), a template wanting what only Hydra's own parser knows
    (``$FLAGS_HELP``, ``$OVERRIDE_ALIASES``) or a config that does not compose (Hydra's message).
    tests/test_hydra_cli.py compares the text with Hydra's own."""
    import copy
    import functools
    import string

    if not ("--help" in args or "-h" in args) or any(a.startswith("-") for a in args if a not in ("--help", "-h")):
        return False
    overrides = [a for a in args if a not in ("--help", "-h")]
    from hydra import compose, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.hydra_config import HydraConfig
    from hydra.core.object_type import ObjectType
    from omegaconf import OmegaConf, flag_override

    try:
        with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
            cfg = compose("config", overrides=overrides, return_hydra_config=True)
            sources = GlobalHydra.instance().config_loader().get_sources()
        HydraConfig.instance().set_config(cfg)
        template = string.Template(str(cfg.hydra.help.template))
    except Exception:
        return False

    @functools.cache
    def options(group: str, kind: ObjectType) -> list[str]:  # Hydra's ConfigRepository.get_group_options
        return sorted({o for s in sources if s.is_group(group) for o in s.list(group, results_filter=kind)})

    def groups(parent: str = "") -> list[str]:  # Hydra's list_all_config_groups
        found: list[str] = []
        for child in options(parent, ObjectType.GROUP):
            name = f"{parent}/{child}" if parent else child
            if options(name, ObjectType.CONFIG):
                found.append(name)
            if options(name, ObjectType.GROUP):
                found.extend(groups(name))
        return found

    def listing(hydras: bool) -> str:  # Hydra's format_config_groups
        chosen = [g for g in groups() if (g == "hydra" or g.startswith("hydra/")) == hydras]
        return "".join(f"{g}: {', '.join(options(g, ObjectType.CONFIG))}\n" for g in sorted(chosen))

    def job() -> str:  # Hydra's get_sanitized_cfg(cfg, "job"), as YAML
        clean = copy.deepcopy(cfg)
        with flag_override(clean, ["struct", "readonly"], [False, False]):
            del clean["hydra"]
        return OmegaConf.to_yaml(clean)

    values = {"APP_CONFIG_GROUPS": lambda: listing(False), "HYDRA_CONFIG_GROUPS": lambda: listing(True), "CONFIG": job}
    wanted = set(template.get_identifiers())
    if not wanted <= values.keys():
        return False
    print(template.substitute({name: values[name]() for name in wanted}))
    return True


def _hint(message: str) -> str:
    """``message``, with what to do where zrp_ga knows better than Hydra's words: a sweep's config
    (``experiment=operator_grid``, ``hparams_search=...``: they set ``hydra.mode: MULTIRUN``) run
    without ``-m`` under hydra-core 1.4, which takes the mode from the command line or the primary
    config only."""
    if "hydra.mode changed during config composition" in message:
        return (f"{message} (a sweep's config, such as experiment=operator_grid or hparams_search=ga_optuna, "
                "runs with -m: zrp-ga -m experiment=...)")  # fmt: skip
    if "Config group override must be a string or a list. Got NoneType" in message:
        nulls = [a.split("=", 1)[0] for a in sys.argv[1:] if a.endswith("=null") and "." not in a.split("=", 1)[0]]
        named = f" ({', '.join(nulls)}=null)" if nulls else ""
        return (f"{message}{named}: a config group takes one of its options, not null; no hyperparameter search is "
                "hparams_search=none (the default), and ~GROUP removes a group's entry")  # fmt: skip
    return message


def version() -> str:
    """``zrp-ga --version``: zrp_ga's version, and the Hydra and OmegaConf it runs on."""
    from importlib import metadata

    return " ".join(f"{name} {metadata.version(name)}" for name in ("zrp_ga", "hydra-core", "omegaconf"))


@contextlib.contextmanager
def _few_collections() -> Iterator[None]:
    """Python's cyclic garbage collector run less often while a run's modules are imported and its
    config composed (many objects, little garbage: 0.1 CPU-s of 370 collections, 75 now), and not
    over the objects that live until the process ends (at its end, the collections over every
    object of numba, scipy and Hydra took 0.3 CPU-s). Nothing a run computes depends on it."""
    import atexit
    import gc

    from zrp_ga.run.shared import few_collections

    atexit.register(gc.freeze)  # runs when the process ends, before Python's last collections
    with few_collections():
        yield


def _continue_with(tuning: tuple[Any, bool] | None = None) -> str:
    """How to continue the interrupted run or sweep, from what Hydra knows about it; ``tuning``:
    the study of an interrupted tuning sweep and whether it was settled
    (:func:`zrp_ga.cli.study.interrupted`)."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if tuning is not None:  # new trials ask for new settings: an interrupted trial's run is not continued
        (study, settled), when = tuning, ""
        if not settled:
            when = " when the study is continued"
        return (f"the finished trials are in the study in {study.sweep} (the unfinished ones marked failed{when}, their runs "
                f"not continued): the same command with hydra.sweep.dir={study.sweep} adds hydra.sweeper.n_trials "
                "new trials")  # fmt: skip
    hc = HydraConfig.get() if HydraConfig.initialized() else None
    if hc is not None and hc.mode == RunMode.MULTIRUN:
        sweep = hc.sweep.dir
        return (f"the finished jobs are kept in {sweep} and the interrupted ones continue from their checkpoints: "
                f"continue with the same command and hydra.sweep.dir={sweep}")  # fmt: skip
    if hc is None:  # a sweep's own process (its jobs run elsewhere), or a run stopped before Hydra set it up
        if _multirun(sys.argv[1:]):
            return ("the finished jobs are kept in the sweep's folder and the interrupted ones continue from their "
                    "checkpoints: continue with the same command (and the same hydra.sweep.dir, if it named one)")  # fmt: skip
        return "stopped before the run started: nothing to continue; run the command again"
    resumed = [o.split("=", 1)[1] for o in hc.overrides.task if o.startswith("resume=")]
    where = Path(resumed[-1]).expanduser() if resumed else hc.runtime.output_dir
    return (f"the checkpoint and convergence.csv in {where} are complete up to the last finished generation: "
            f"continue with zrp-ga resume={where}")  # fmt: skip


def _multirun(args: list[str]) -> bool:
    """Whether the command line asks for a sweep (``-m``, ``--multirun``, ``hydra.mode=MULTIRUN``)."""
    return any(a in ("-m", "--multirun") or a.replace(" ", "") == "hydra.mode=MULTIRUN" for a in args)


def _register_launcher() -> None:
    """zrp_ga's launcher, registered through Hydra's public ``Plugins.register`` when Hydra did
    not find it: hydra-core 1.3 finds plugins only by listing the modules of the
    ``hydra_plugins`` namespace package, which an editable install (``pip install -e``, whose
    import hook cannot be listed) hides from it (1.4 also reads the entry point in pyproject.toml)."""
    from hydra.core.plugins import Plugins
    from hydra.plugins.launcher import Launcher

    from hydra_plugins.zrp_ga_launcher.launcher import ZrpGaLauncher

    if ZrpGaLauncher not in Plugins.instance().discover(Launcher):
        Plugins.instance().register(ZrpGaLauncher)
    from hydra.plugins.sweeper import Sweeper

    from hydra_plugins.zrp_ga_sweeper.sweeper import ZrpGaSweeper  # hydra/sweeper=zrp_ga

    if ZrpGaSweeper not in Plugins.instance().discover(Sweeper):
        Plugins.instance().register(ZrpGaSweeper)


def _stop(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt
