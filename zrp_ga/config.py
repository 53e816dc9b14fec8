"""Hydra's side of the config: the schema registered in Hydra's ConfigStore, configs composed from
``conf/`` and turned into the typed :class:`~zrp_ga.core.schema.Config`, and what differs
between the Hydra releases zrp_ga supports.

The schema itself (the dataclasses, the checks, plain values and back) is
:mod:`zrp_ga.core.schema`, which knows nothing of Hydra: the run layer and everything below it
take the typed config. This module is for the entry points only: the command line
(:mod:`zrp_ga.cli`), zrp_ga's launcher (``hydra_plugins/zrp_ga_launcher``) and the API
(:func:`zrp_ga.calibrate`), which compose configs with Hydra.

The schema's dataclasses are stored in Hydra's ConfigStore when this module is imported (once per
process: hydra-core 1.4 warns about a name stored twice, 1.5 refuses it): ``config_schema`` is the
first entry of ``conf/config.yaml``'s defaults list, and the options of the ``problem`` and
``algorithm`` groups extend their kind's schema (``- /ga_schema@_here_`` in
``conf/algorithm/ga.yaml``). A key that is not in the schema (``problem.n_pose=30``), a value of
the wrong type or a bad Enum value (``algorithm.strategy=steady``) fails at composition, before
anything runs. zrp_ga's launcher keeps its own settings (``hydra/launcher=zrp_ga``) in
``hydra_plugins/zrp_ga_launcher/config.py``, as Hydra's launcher plugins do.
"""

from __future__ import annotations

import enum
import functools
import re
from collections.abc import Callable
from typing import Any, Protocol

from omegaconf import DictConfig, ListConfig, OmegaConf

from zrp_ga.core import schema

# Stored at the root of the config tree, not in a group, so that they are no options of their own
# (a group option extends one with ``- /ga_schema@_here_`` in its defaults list).
SCHEMAS = {"config_schema": schema.Config, "ga_schema": schema.GAConf, "lm_schema": schema.LMConf,
           "cmaes_schema": schema.CMAESConf, "simulated_schema": schema.SimulatedConf,
           "measured_schema": schema.MeasuredConf, "pose_selection_schema": schema.PoseSelectionConf,
           "random_search_schema": schema.RandomSearchConf, "exchange_schema": schema.ExchangeConf}  # fmt: skip


def _register() -> None:
    from hydra.core.config_store import ConfigStore

    cs = ConfigStore.instance()
    for name, node in SCHEMAS.items():
        cs.store(name=name, node=node, provider="zrp_ga")


_register()


# --- resolvers of the tuning configs (conf/hparams_search) -----------------------------------------
def _sqlite(path: str) -> str:
    """``${zrp_ga.sqlite:PATH}``: the URL of an SQLite database at ``PATH`` (an Optuna storage), its
    folder made (Optuna opens the database before the sweep's folder exists)."""
    from pathlib import Path

    where = Path(path).expanduser().absolute()
    where.parent.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{where.as_posix()}"


def study_size(storage: str | None, study_name: str | None) -> int:
    """``${zrp_ga.study_size:STORAGE,STUDY}``: the trials the Optuna study holds (0 without a
    storage, or before the study's first run). Cached per config (and copied from the sweep's
    config to its jobs', as Hydra copies its resolvers' cache): the study's size when the sweep
    started, the first trial number of this run of it. The tuning configs number their jobs'
    folders and seeds from it, so that a run continuing a study neither reuses a folder nor
    repeats its sampler's proposals (its sampler's seed)."""
    if not storage or not study_name:
        return 0
    import optuna

    return next((s.n_trials for s in optuna.study.get_all_study_summaries(storage) if s.study_name == study_name), 0)  # Optuna 2.10 - 5


def _add(*values: Any) -> int:
    """``${zrp_ga.add:A,B}``: the sum of integers."""
    return sum(int(v) for v in values)


class _Register(Protocol):
    """OmegaConf's resolver registration taking ``replace`` and ``use_cache`` (2.4.1's
    ``register_resolver``, 2.3's ``register_new_resolver``)."""

    def __call__(self, name: str, resolver: Callable[..., Any], *, replace: bool = False, use_cache: bool = False) -> None: ...


def _register_resolvers() -> None:
    """The resolvers, through OmegaConf's ``register_resolver`` where it takes ``use_cache``
    (OmegaConf 2.4.1, which deprecates ``register_new_resolver``), else ``register_new_resolver``
    (2.3, whose ``register_resolver`` is the legacy one)."""
    import inspect

    # By name: the one chosen takes ``replace`` and ``use_cache`` in either version, which the
    # installed version's stubs cannot tell for both (2.3's ``register_resolver`` takes neither).
    name = "register_resolver" if "use_cache" in inspect.signature(OmegaConf.register_resolver).parameters else "register_new_resolver"
    register: _Register = getattr(OmegaConf, name)
    register("zrp_ga.sqlite", _sqlite, replace=True)
    register("zrp_ga.study_size", study_size, use_cache=True, replace=True)
    register("zrp_ga.add", _add, replace=True)


_register_resolvers()


def compose(overrides: list[str] | tuple[str, ...] = (), return_hydra_config: bool = False) -> DictConfig:
    """The config Hydra composes for ``overrides``, as ``zrp-ga`` would see it (with its ``hydra``
    node if ``return_hydra_config``)."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_module

    launcher_stored()
    with initialize_config_module("zrp_ga.conf", **hydra_options()):
        return hydra_compose("config", overrides=list(overrides), return_hydra_config=return_hydra_config)


def launcher_stored() -> None:
    """zrp_ga's launcher's and sweeper's settings (``hydra/launcher=zrp_ga``, which
    ``conf/config.yaml``'s default launcher extends; ``hydra/sweeper=zrp_ga``, which
    ``hparams_search=none``, the default, chooses) in Hydra's ConfigStore, as Hydra's plugin
    discovery stores them when it imports the plugins: hydra-core 1.3 does not find them in an
    editable install (``pip install -e``), whose import hook its scan of the ``hydra_plugins``
    package cannot list, and a config composed by ``zrp_ga.calibrate`` or ``zrp_ga.config.load``
    has no plugin scan before it. Imported by name (the plugins are above this module's layer, as
    Hydra's discovery imports them)."""
    import importlib

    from hydra.core.config_store import ConfigStore

    for group, module in (("hydra/launcher", "hydra_plugins.zrp_ga_launcher.config"),
                          ("hydra/sweeper", "hydra_plugins.zrp_ga_sweeper.sweeper")):  # fmt: skip
        try:
            stored = "zrp_ga.yaml" in ConfigStore.instance().list(group)
        except OSError:  # nothing stored in the group yet
            stored = False
        if not stored:
            try:
                importlib.import_module(module)
            except ImportError:  # the plugin not installed: Hydra names the missing option
                pass


def load(overrides: list[str] | tuple[str, ...] = ()) -> schema.Config:
    """The typed config of ``overrides`` (:func:`compose`, then :func:`typed`), ready for the run
    layer (for tests, notebooks and experiment scripts)."""
    return typed(compose(overrides))


def typed(cfg: DictConfig) -> schema.Config:
    """A composed config (its ``hydra`` node left out) as the typed
    :class:`~zrp_ga.core.schema.Config`: :func:`resolved`, then
    :func:`~zrp_ga.core.schema.from_dict`, equal to ``OmegaConf.to_object`` of it
    (tests/test_config.py) and several times faster (a sweep converts every job's config)."""
    return schema.from_dict(resolved(cfg))


def resolved(cfg: DictConfig) -> dict:
    """``OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)`` without the ``hydra`` node:
    the config as its files record it, with the interpolations that name another node of ``cfg``
    (``algorithm.population: ${population}``) copied from that node rather than resolved one by
    one; any other interpolation: OmegaConf resolves the whole."""
    raw = {k: _plain(v) for k, v in cfg.items_ex(resolve=False) if k != "hydra"}

    def filled(o: Any, seen: tuple[str, ...]) -> Any:
        if isinstance(o, dict):
            return {k: filled(v, seen) for k, v in o.items()}
        if isinstance(o, list):
            return [filled(v, seen) for v in o]
        if isinstance(o, str) and "${" in o:
            path = _NODE.fullmatch(o)
            target = _at(raw, path[1]) if path and path[1] not in seen else None
            if path is None or not isinstance(target, (dict, list)):
                raise _Unresolved
            return filled(target, (*seen, path[1]))
        return o

    try:
        return filled(raw, ())
    except _Unresolved:
        return {k: _plain(cfg[k] if isinstance(v, str) and "${" in v else v, resolve=True)  # a value interpolated: resolved
                for k, v in cfg.items_ex(resolve=False) if k != "hydra"}  # fmt: skip


_NODE = re.compile(r"\$\{([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)\}")  # ${a.b}: a reference to a node, from the root


def _plain(value: Any, resolve: bool = False) -> Any:
    """A top-level value of a config (as ``DictConfig.items_ex`` gives it) as plain values."""
    if isinstance(value, (DictConfig, ListConfig)):
        return OmegaConf.to_container(value, resolve=resolve, enum_to_str=True)
    return value.name if isinstance(value, enum.Enum) else value


class _Unresolved(Exception):
    """An interpolation :func:`resolved` leaves to OmegaConf."""


def _at(tree: Any, path: str) -> Any:
    """The value at dotted ``path`` in nested dicts (None if there is none)."""
    for part in path.split("."):
        if not isinstance(tree, dict) or part not in tree:
            return None
        tree = tree[part]
    return tree


# --- what differs between the Hydra releases zrp_ga supports (hydra-core 1.3.2 - 1.4) -------------
# The targets zrp_ga's configs name; hydra-core 1.4 asks for them to be declared (its "execution
# whitelist") and warns about others, which 1.5 will refuse. (The run layer builds its objects
# itself, zrp_ga.core.targets: Hydra instantiates only its own callbacks, launcher and sweeper.)
TRUSTED_TARGETS = ["zrp_ga.*", "deap.*", "hydra_plugins.*"]


@functools.cache
def hydra_14() -> bool:
    """Whether the installed hydra-core is 1.4 or later."""
    from importlib import metadata

    major, minor = (int("".join(c for c in part if c.isdigit()) or 0) for part in metadata.version("hydra-core").split(".")[:2])
    return (major, minor) >= (1, 4)


def hydra_options() -> dict[str, Any]:
    """Keyword arguments of ``hydra.main`` and ``initialize_config_module``: Hydra's defaults of
    the installed release (1.3 and 1.4 give zrp_ga the same config; the output directory never
    is the working directory, conf/config.yaml sets ``hydra.job.chdir=false``). 1.3 wants
    ``version_base`` (else the defaults of 1.1), 1.4 warns about it."""
    return {} if hydra_14() else {"version_base": None}
