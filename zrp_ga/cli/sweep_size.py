"""A sweep's largest job checked against the memory this process may use, once, before any job
starts (:mod:`zrp_ga.run.budget`): :class:`zrp_ga.cli.callbacks.Manifest` calls :func:`check`
as the sweep begins, so that a sweep too big for its machine, container or job is refused with
one line and no directory, not job by job after the first ones ran.

The jobs are those of Hydra's basic sweeper (and of zrp_ga's, ``-m``'s default, which expands the same grid): its ``hydra.sweeper.params`` and the command
line's overrides, every combination of their values (as ``BasicSweeper.split_arguments``
forms them). Only the overrides that can change a run's size are combined: those of the
operators, the seed and the run's bookkeeping (:data:`SIZELESS`) cannot, so a sweep over
operators and seeds is one size, its config the sweep's own (nothing composed); the others are
composed once per combination with Hydra's config loader (``load_sweep_config``, as the sweeper
composes each job). Another sweeper (Optuna's, whose jobs are chosen as it goes): the sweep's
own config is checked, and each job checks itself as it starts.
"""

from __future__ import annotations

import copy
import itertools
import json
from collections.abc import Iterator
from typing import Any

from hydra.core.override_parser.types import OverrideType
from omegaconf import DictConfig, OmegaConf, open_dict

BASIC_SWEEPER = ".BasicSweeper"  # the end of Hydra's basic sweeper's _target_ (a private module's name: not imported)
GRID_SWEEPERS = (BASIC_SWEEPER, ".ZrpGaSweeper")  # zrp_ga's (hydra_plugins/zrp_ga_sweeper): the basic sweeper's grid
SIZELESS = ("seed", "progress", "checkpoint_every", "objective", "resume", "selection", "crossover", "mutation",
            "inversion", "rotation", "refine")  # fmt: skip


def _sizeless(key: str) -> bool:
    head = key.lstrip("+~").split("@")[0].replace("/", ".").split(".")[0]
    return head in SIZELESS


def jobs(config: DictConfig) -> Iterator[tuple[str, DictConfig]]:
    """The sweep's jobs that may differ in size: (their size-changing overrides, their config);
    one job with the sweep's own config when no override changes the size (module docstring).
    Each combination of group options is composed once; the values swept (``population.mu=50``)
    are set on it in place, as Hydra sets a value override: a config holds until the next is
    given (every job of a composition sets the same keys)."""
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.override_parser.overrides_parser import OverridesParser

    sweeper = config.hydra.sweeper
    if not str(getattr(sweeper, "_target_", "")).endswith(GRID_SWEEPERS):
        yield "", config
        return
    params = [f"{k}={v}" for k, v in (getattr(sweeper, "params", None) or {}).items()]
    loader = GlobalHydra.instance().config_loader()
    parsed = OverridesParser.create(config_loader=loader).parse_overrides(params + list(config.hydra.overrides.task))
    # the command line's single values (the sweep's config has them), the params', the values swept: (override, value, text)
    own: list[tuple[Any, Any, str]] = []
    added: list[tuple[Any, Any, str]] = []
    varied: list[list[tuple[Any, Any, str]]] = []
    for k, o in enumerate(parsed):
        if o.is_sweep_override() and not o.is_discrete_sweep():
            yield "", config  # a range of floats: the basic sweeper refuses it itself
            return
        if _sizeless(o.key_or_group) and (o.is_sweep_override() or k < len(params)):
            continue
        if o.is_sweep_override():
            varied.append([(o, v, f"{o.get_key_element()}={s}") for v, s in zip(o.sweep_iterator(), o.sweep_string_iterator())])
        else:
            (added if k < len(params) else own).append((o, o.value(), f"{o.get_key_element()}={o.get_value_element_as_str()}"))
    if not varied and not added:
        yield "", config  # only what the sweep's own config has
        return
    groups = set(loader.list_groups(""))
    is_value = lambda o: o.type == OverrideType.CHANGE and o.package is None and o.key_or_group not in groups
    options_of = lambda every: tuple(text for o, _, text in every if not is_value(o))
    composed: dict[tuple[str, ...], DictConfig] = {}
    for combo in itertools.product(*varied):
        every = added + own + list(combo)
        options = options_of(every)
        if options not in composed:  # the sweep's own config when it has these options (a copy: values are set on it)
            same = options == options_of(own)
            composed[options] = copy.deepcopy(config) if same else loader.load_sweep_config(config, list(options))
        cfg = composed[options]
        with open_dict(cfg):
            for o, value, _ in every:
                if is_value(o):
                    OmegaConf.update(cfg, o.key_or_group, value, merge=True)
        yield " ".join(text for _, _, text in combo), cfg


def check(config: DictConfig) -> None:
    """Refuse the sweep of ``config`` (ValueError, one line) when its largest job does not fit
    (:func:`zrp_ga.run.budget.check`). A job whose robot, problem or optimiser cannot be built
    (a bad value, a missing file) is left to fail alone, as its job, recorded in the manifest."""
    from zrp_ga.config import typed
    from zrp_ga.core import schema, targets
    from zrp_ga.run import budget

    robots: dict[str, Any] = {}
    worst: tuple[float, str, Any] | None = None
    for label, composed in jobs(config):
        try:
            cfg = typed(composed)
            key = json.dumps(schema.to_dict(cfg.robot), sort_keys=True, default=str)
            if key not in robots:
                robots[key] = targets.create(cfg.robot, "robot")
            e = budget.of_config(cfg, robots[key])
        except (ValueError, OSError):
            continue
        if worst is None or e.bytes > worst[0]:
            worst = (e.bytes, label, e)
    if worst is not None:
        what = f"the sweep's largest job ({worst[1]})" if worst[1] else "each job of the sweep"
        budget.check(worst[2], what=what)
