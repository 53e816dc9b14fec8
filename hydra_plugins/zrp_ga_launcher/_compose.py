"""Job configs of a sweep, equal to Hydra's own and composed from a few of them.

Hydra composes every job of a sweep from scratch (``ConfigLoaderImpl.load_sweep_config``: the
defaults list, every file loaded and merged, the overrides applied), 0.2 - 0.3 s a job here,
twice per job (the sweeper checks each job before the launcher composes it again): more than
the run of a small job. :class:`ComposingLoader` is Hydra's loader with that one method
answering from compositions Hydra made:

- jobs whose overrides differ only in values (``seed=3``, ``population.mu=50``) share one of
  Hydra's compositions, onto which each job's values are applied by Hydra's own
  ``_apply_overrides_to_config`` (values of the same keys and types, so that the result does
  not depend on the values applied before);
- jobs that also choose other options of config groups (``crossover=sbx``) take the composition
  of a first job and, for each group whose option differs, the group's subtree from Hydra's
  composition of that first job with only that option changed. This holds when the option
  writes into its own package only: the two defaults lists then differ only in entries inside
  that package, so that everything outside it comes from the same files in the same order.
  That is checked on the defaults lists Hydra made, and the composition with the option changed
  must give the first one back when the first subtree is put back;
- an option that is not separable so (an option with a ``@package _global_`` header, such as
  ``instance=...``, one choosing other groups' options, packages inside each other) is composed
  by Hydra once per shape and combination of such options, and that composition is then the
  first job of the jobs sharing them (a suite sweep: one per instance, not one per job).

Every job's ``hydra`` node is then completed as Hydra does: ``overrides.task``, the
``override_dirname`` and the choices. tests/test_sweeps.py compares the configs (YAML, node
types, flags) with Hydra's own over whole sweeps. This uses Hydra's internal loader, which is
why ``hydra-core`` is pinned below 1.4; ``hydra.launcher.cached_composition=false`` turns it off.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import logging
import pickle
from collections.abc import Iterator
from typing import Any

from hydra._internal.config_loader_impl import ConfigLoaderImpl, get_overrides_dirname
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override, OverrideType
from omegaconf import DictConfig, OmegaConf

Shape = tuple  # one entry per override: ("group", key), ("value", key, type name) or ("line", text)


@dataclasses.dataclass
class _Composed:
    """One of Hydra's compositions: the config (pickled: unpickling copies it faster than
    ``copy.deepcopy``), the override lines it was made with, its defaults list and choices."""

    data: bytes
    lines: list[str]
    options: dict[str, str]
    defaults: list[tuple]
    choices: dict[str, Any]
    config: DictConfig | None = None  # kept for the subtrees of a composition with one option changed
    package: str | None = None  # the changed group's package, for such a composition


class ComposingLoader(ConfigLoaderImpl):
    """Hydra's config loader, with :meth:`load_sweep_config` composing from a few of Hydra's
    compositions (see the module docstring). ``enabled=False``: Hydra's own, every time."""

    def __init__(self, config_search_path: Any, enabled: bool = True) -> None:
        super().__init__(config_search_path)
        self.enabled = enabled
        self.hydra_compositions = 0  # how many compositions Hydra made (for tests and benchmarks)
        self._parsed: dict[str, Override] = {}
        self._groups: dict[str, bool] = {}
        self._templates: dict[tuple, _Composed] = {}  # (shape, options) -> Hydra's composition
        self._bases: dict[Shape, _Composed] = {}  # shape -> the first composition of that shape
        self._variants: dict[tuple, _Composed | None] = {}  # (shape, base lines, group, option) -> None if not separable
        self._fixed_bases: dict[tuple, _Composed] = {}  # (shape, non-separable options) -> the first composition with them
        self._last_defaults: list[tuple] = []

    @classmethod
    def wrap(cls, loader: ConfigLoaderImpl, enabled: bool = True) -> ComposingLoader:
        return loader if isinstance(loader, cls) else cls(loader.config_search_path, enabled)

    # --- Hydra's own, recording the defaults list ----------------------------------------------
    def _compose_config_from_defaults_list(self, defaults: list, repo: Any) -> DictConfig:
        self._last_defaults = [(d.config_path, d.package, d.parent, d.is_self) for d in defaults]
        return super()._compose_config_from_defaults_list(defaults, repo)

    def _hydra(self, master: DictConfig, lines: list[str], options: dict[str, str]) -> tuple[DictConfig, _Composed]:
        hydra_lines = list(master.hydra.overrides.hydra)
        cfg = super().load_sweep_config(master, lines[len(hydra_lines) :])
        self.hydra_compositions += 1
        composed = _Composed(pickle.dumps(cfg), list(lines), dict(options), self._last_defaults,
                             OmegaConf.to_container(cfg.hydra.runtime.choices))  # fmt: skip
        return cfg, composed

    # --- the sweep's jobs -------------------------------------------------------------------------
    def load_sweep_config(self, master_config: DictConfig, sweep_overrides: list[str]) -> DictConfig:
        if not self.enabled or OmegaConf.select(master_config, "hydra.searchpath"):
            return super().load_sweep_config(master_config, sweep_overrides)
        lines = [*master_config.hydra.overrides.hydra, *sweep_overrides]
        overrides = [self._parse(line) for line in lines]
        shape, options, values = self._classify(overrides)
        key = (shape, tuple(options.items()))
        cfg = None if key in self._templates else self._from_base(master_config, shape, options)
        if cfg is None:
            template = self._templates.get(key)  # perhaps composed on the way, as a group's variant
            if template is None:
                cfg, self._templates[key] = self._hydra(master_config, lines, options)
                first = self._bases.setdefault(shape, self._templates[key])
                fixed = self._fixed(master_config, shape, first, options)
                if fixed:
                    self._fixed_bases.setdefault((shape, fixed), self._templates[key])
                return cfg
            cfg = pickle.loads(template.data)
        self._complete(cfg, overrides, values)
        OmegaConf.copy_cache(from_config=master_config, to_config=cfg)
        return cfg

    def _parse(self, line: str) -> Override:
        if line not in self._parsed:
            self._parsed[line] = OverridesParser.create().parse_overrides([line])[0]
        return self._parsed[line]

    def _is_group(self, key: str) -> bool:
        if key not in self._groups:
            self._groups[key] = self.repository.group_exists(key)
        return self._groups[key]

    def _classify(self, overrides: list[Override]) -> tuple[Shape, dict[str, str], list[Override]]:
        """The shape of a job's overrides, its group options and its value overrides."""
        shape, options, values = [], {}, []
        for o in overrides:
            plain = (o.type == OverrideType.CHANGE and o.package is None and not o.is_hydra_override()
                     and not o.is_sweep_override())  # fmt: skip
            value = o.value() if plain else None
            if plain and self._is_group(o.key_or_group) and isinstance(value, str):
                shape.append(("group", o.key_or_group))
                options[o.key_or_group] = value
            elif plain and not self._is_group(o.key_or_group) and isinstance(value, (str, int, float, bool, type(None))):
                shape.append(("value", o.key_or_group, type(value).__name__))
                values.append(o)
            else:
                shape.append(("line", o.input_line))
        return tuple(shape), options, values

    def _from_base(self, master: DictConfig, shape: Shape, options: dict[str, str]) -> DictConfig | None:
        """The first composition of ``shape`` with the subtrees of the groups whose option
        differs put in; None when a group is not separable (see the module docstring)."""
        base = self._bases.get(shape)
        if base is None:
            return None
        fixed = self._fixed(master, shape, base, options)
        if fixed:  # the first composition with the same options that are not separable, if any
            base = self._fixed_bases.get((shape, fixed))
            if base is None:
                return None
        changed = [self._variant(master, shape, base, g, o) for g, o in options.items() if base.options[g] != o]
        if any(v is None for v in changed) or not _disjoint([v.package for v in changed]):
            return None
        cfg = pickle.loads(base.data)
        for variant in changed:
            _put(cfg, variant.package, OmegaConf.select(variant.config, variant.package))
            group = next(g for g in options if variant.options[g] != base.options[g])
            cfg.hydra.runtime.choices[group] = variant.options[group]
        return cfg

    def _fixed(self, master: DictConfig, shape: Shape, base: _Composed, options: dict[str, str]) -> tuple:
        """The options of ``options`` that differ from ``base``'s and are not separable from it."""
        return tuple(sorted((g, o) for g, o in options.items()
                            if base.options[g] != o and self._variant(master, shape, base, g, o) is None))  # fmt: skip

    def _variant(self, master: DictConfig, shape: Shape, base: _Composed, group: str, option: str) -> _Composed | None:
        """Hydra's composition of ``base``'s overrides with ``group=option``, if separable. One
        that is not is kept as the first composition with that option (``_fixed_bases``)."""
        key = (shape, tuple(base.lines), group, option)
        if key not in self._variants:
            lines = [f"{group}={option}" if (s[0] == "group" and s[1] == group) else line for s, line in zip(shape, base.lines)]
            cfg, variant = self._hydra(master, lines, {**base.options, group: option})
            variant.package = _changed_package(base, variant, group)
            if variant.package is not None and not _gives_back(cfg, base, variant.package, group):
                variant.package = None
            variant.config = cfg
            self._variants[key] = variant if variant.package is not None else None
            self._templates.setdefault((shape, tuple(variant.options.items())), variant)
            if variant.package is None:
                fixed = tuple(sorted((g, o) for g, o in variant.options.items() if base.options[g] != o))
                self._fixed_bases.setdefault((shape, fixed), variant)
        return self._variants[key]

    @staticmethod
    def _complete(cfg: DictConfig, overrides: list[Override], values: list[Override]) -> None:
        """What Hydra sets from a job's overrides: the values, ``overrides.task`` and the
        ``override_dirname`` (the choices are set by the caller)."""
        ConfigLoaderImpl._apply_overrides_to_config(values, cfg)
        task = [o for o in overrides if not o.is_hydra_override()]
        for k, o in enumerate(task):
            cfg.hydra.overrides.task[k] = o.input_line
        names = cfg.hydra.job.config.override_dirname
        cfg.hydra.job.override_dirname = get_overrides_dirname(
            overrides=task, kv_sep=names.kv_sep, item_sep=names.item_sep, exclude_keys=names.exclude_keys
        )


def _inside(package: str, root: str) -> bool:
    return package == root or package.startswith(root + ".")


def _disjoint(packages: list[str]) -> bool:
    return not any(a is not b and _inside(a, b) for a in packages for b in packages)


def _changed_package(base: _Composed, variant: _Composed, group: str) -> str | None:
    """The package of ``group``'s option when the two defaults lists differ only inside it and
    the choices only in ``group``; else None."""
    old = [d for d in base.defaults if d[0] == f"{group}/{base.options[group]}"]
    new = [d for d in variant.defaults if d[0] == f"{group}/{variant.options[group]}"]
    if len(old) != 1 or len(new) != 1 or old[0][1] != new[0][1] or not old[0][1]:
        return None
    package = old[0][1]
    rest = [[d for d in c.defaults if not (d[1] is not None and _inside(d[1], package))] for c in (base, variant)]
    if rest[0] != rest[1] or list(base.choices) != list(variant.choices):
        return None
    if any(base.choices[k] != variant.choices[k] for k in base.choices if k != group):
        return None
    return package


def _gives_back(cfg: DictConfig, base: _Composed, package: str, group: str) -> bool:
    """The composition with ``group``'s option changed equals ``base`` once ``base``'s subtree,
    choice and override lines are put back (an empirical check of separability)."""
    first, other = pickle.loads(base.data), pickle.loads(pickle.dumps(cfg))
    _put(other, package, OmegaConf.select(first, package))
    other.hydra.runtime.choices[group] = base.options[group]
    for k, line in enumerate(first.hydra.overrides.task):
        other.hydra.overrides.task[k] = line
    other.hydra.job.override_dirname = first.hydra.job.override_dirname
    return OmegaConf.to_yaml(other) == OmegaConf.to_yaml(first)


def _put(cfg: DictConfig, package: str, node: Any) -> None:
    """Replace the subtree at the dotted ``package`` of ``cfg`` by a copy of ``node``, a node
    of the same schema field in another composition. The node object is swapped in whole:
    assigning it would rebuild it key by key (OmegaConf's ``_set_value``), at ten times the cost,
    to the same nodes (the tests compare node types and flags)."""
    parent, _, leaf = package.rpartition(".")
    target = OmegaConf.select(cfg, parent) if parent else cfg
    new = copy.deepcopy(node)
    new._set_parent(target)
    target.__dict__["_content"][leaf] = new


@contextlib.contextmanager
def compose_once() -> Iterator[None]:
    """While active, a Hydra app composes its config once instead of twice.

    ``hydra.main`` composes the config to read ``hydra.mode`` (``Hydra.get_mode``, in multirun
    mode, where sweep overrides are not checked and missing options are skipped), then composes
    it again to run (0.2 - 0.3 s each here). The first composition is kept and given to the
    second when the second could not differ: no sweep overrides (for a single run), no missing
    option, and the same overrides but for ``hydra.mode=RUN`` or ``=MULTIRUN``, which Hydra
    appends when no config set the mode; that override is then applied as Hydra applies it
    (``_apply_overrides_to_config``, and the line appended to ``hydra.overrides.hydra``).
    tests/test_sweeps.py compares the result with Hydra's own composition."""
    from hydra._internal import hydra as hydra_module
    from hydra.types import RunMode

    Hydra = hydra_module.Hydra
    get_mode, compose = Hydra.get_mode, Hydra.compose_config
    kept: dict[tuple, DictConfig] = {}

    def first(self: Any, config_name: str | None, overrides: list[str]) -> Any:
        try:
            cfg = compose(self, config_name=config_name, overrides=overrides, run_mode=RunMode.MULTIRUN,
                          with_log_configuration=False, validate_sweep_overrides=False)  # fmt: skip
        except Exception:  # as Hydra's get_mode: the next composition raises it
            return None
        kept[(config_name, tuple(overrides))] = cfg
        return cfg.hydra.mode

    def again(self: Any, config_name: str | None, overrides: list[str], run_mode: Any,
              with_log_configuration: bool = False, from_shell: bool = True, validate_sweep_overrides: bool = True) -> DictConfig:  # fmt: skip
        cfg = _reuse(kept, config_name, overrides, run_mode)
        if cfg is None:
            return compose(self, config_name, overrides, run_mode, with_log_configuration, from_shell, validate_sweep_overrides)
        if with_log_configuration:  # what Hydra's compose_config does then
            from hydra.core.utils import configure_log

            configure_log(cfg.hydra.hydra_logging, cfg.hydra.verbose)
            hydra_module.log = logging.getLogger(hydra_module.__name__)
            self._print_debug_info(config_name, overrides, run_mode)
        return cfg

    Hydra.get_mode, Hydra.compose_config = first, again
    try:
        yield
    finally:
        Hydra.get_mode, Hydra.compose_config = get_mode, compose


def _reuse(kept: dict, config_name: str | None, overrides: list[str], run_mode: Any) -> DictConfig | None:
    """The kept composition for ``overrides`` (see :func:`compose_once`), or None."""
    from hydra.types import RunMode

    mode_lines = {f"hydra.mode={m.name}" for m in RunMode}
    extra = overrides[-1:] if overrides and overrides[-1] in mode_lines else []
    cfg = kept.pop((config_name, tuple(overrides[: len(overrides) - len(extra)])), None)
    parsed = OverridesParser.create().parse_overrides(list(overrides))
    choices = cfg.hydra.runtime.choices if cfg is not None else {}
    if cfg is None or any(OmegaConf.is_missing(choices, k) for k in choices):
        return None
    if any(o.is_sweep_override() and (run_mode == RunMode.RUN or o.is_hydra_override()) for o in parsed):
        return None  # Hydra's composition refuses these
    if extra:
        ConfigLoaderImpl._apply_overrides_to_config(parsed[-1:], cfg)
        cfg.hydra.overrides.hydra.append(extra[0])
    return cfg


@contextlib.contextmanager
def group_options_once() -> Iterator[None]:
    """While active, Hydra's config loader lists the options of config groups from one copy of
    its config repository per (config name, overrides), instead of a deep copy of the whole
    repository (zrp_ga's structured schemas included) for every group it is asked about:
    ``zrp-ga --help`` asks about 115 groups, which took 3 s here. The listing only reads the
    copy (``CachingConfigRepository.get_group_options``), so sharing it changes no answer;
    tests/test_app.py compares the help text with Hydra's own."""
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra.core.object_type import ObjectType

    original = ConfigLoaderImpl.get_group_options

    def get_group_options(self: Any, group_name: str, results_filter: Any = ObjectType.CONFIG,
                          config_name: str | None = None, overrides: list[str] | None = None) -> list[str]:  # fmt: skip
        repos = self.__dict__.setdefault("_zrp_ga_listing_repos", {})
        key = (config_name, tuple(overrides or ()))
        if key not in repos:
            repos[key] = self._parse_overrides_and_create_caching_repo(config_name, list(overrides or ()))[1]
        return repos[key].get_group_options(group_name, results_filter)

    ConfigLoaderImpl.get_group_options = get_group_options
    try:
        yield
    finally:
        ConfigLoaderImpl.get_group_options = original
