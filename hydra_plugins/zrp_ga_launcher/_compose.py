"""Job configs of a sweep, equal to Hydra's own and composed from a few of them, through Hydra's
public interfaces only.

Hydra composes every job of a sweep from scratch (the config loader's ``load_sweep_config``:
the defaults list, every file loaded and merged, the overrides applied), 0.2 - 0.3 s a job
here, twice per job (the sweeper checks each job before the launcher composes it again): more
than the run of a small job. :class:`ComposingLoader` is a config loader (Hydra's public
``ConfigLoader`` interface) that hands every call to Hydra's own loader, but for
``load_sweep_config``, which answers from compositions Hydra made:

- jobs whose overrides differ only in values (``seed=3``, ``population.mu=50``) share one of
  Hydra's compositions, onto which each job's values are applied as Hydra applies a value
  override (``OmegaConf.update(cfg, key, value, merge=True)``; values of the same keys and
  types, so that the result does not depend on the values applied before);
- jobs that also choose other options of config groups (``crossover=sbx``) take the composition
  of a first job and, for each group whose option differs, the group's subtree from Hydra's
  composition of that first job with only that option changed. This holds when the option
  writes into its own package only: the two defaults lists (the loader's public
  ``compute_defaults_list``) then differ only in entries inside that package, so that
  everything outside it comes from the same files in the same order, and the composition with
  the option changed must give the first one back when the first subtree is put back;
- an option that is not separable so (an option with a ``@package _global_`` header, such as
  ``instance=...``, one choosing other groups' options, packages inside each other) is composed
  by Hydra once per shape and combination of such options, and that composition is then the
  first job of the jobs sharing them (a suite sweep: one per instance, not one per job).

Every job's ``hydra`` node is then completed as Hydra does: ``overrides.task``, the
``override_dirname`` (a value in hydra-core 1.3, which is computed here as Hydra computes it;
an interpolation of the task overrides in 1.4, left as it is) and the choices.
tests/test_sweeps.py compares the configs (YAML, node types, flags) with Hydra's own over whole
sweeps. A Hydra release that changes what this relies on can make sweeps slower, never wrong:
``hydra.launcher.cached_composition=false`` (and any sweep with ``hydra.searchpath``) uses
Hydra's own composition for every job.

Hydra's sweeper composes every job once to check it before the launch, and the launcher needs
each job again: the loader keeps what it composed for that second call, as configs for the first
``KEEP_ASKED`` jobs, or, when the launcher asks for a note of each job (``note``: zrp_ga's batch
key), as the notes and the configs pickled and compressed (:meth:`ComposingLoader.pickled_config`).
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import os
import pickle
import re
import signal
import zlib
from collections.abc import Callable
from typing import Any

from hydra.core.config_loader import ConfigLoader
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override, OverrideType
from hydra.errors import ConfigCompositionException
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

KEEP_ASKED = 1024  # job configs kept between the sweeper's check and the launcher's call
KEEP_PICKLED_BYTES = 256 * 2**20  # with notes, instead: the jobs' configs pickled and compressed, in all
Shape = tuple  # one entry per override: ("group", key), ("value", key, type name) or ("line", text)


@dataclasses.dataclass
class _Composed:
    """One of Hydra's compositions: the config (pickled: unpickling copies it faster than
    ``copy.deepcopy``), the override lines it was made with, its config name, choices and
    defaults list."""

    data: bytes
    lines: list[str]
    options: dict[str, str]
    config_name: str
    choices: dict[str, Any]
    defaults: list[tuple] | None = None  # its defaults list, when asked for (ComposingLoader._defaults)
    config: DictConfig | None = None  # kept for the subtrees of a composition with one option changed
    package: str | None = None  # the changed group's package, for such a composition


class ComposingLoader(ConfigLoader):
    """A config loader handing every call to Hydra's ``loader``, with :meth:`load_sweep_config`
    composing from a few of Hydra's compositions (see the module docstring).
    ``enabled=False``: Hydra's own, every time."""

    def __init__(self, loader: ConfigLoader, enabled: bool = True, prefetch: bool = True) -> None:
        self.loader = loader
        self.enabled = enabled
        self.prefetch = prefetch  # the variants a sweep's groups need composed ahead, on every core
        self.hydra_compositions = 0  # how many compositions Hydra made (for tests and benchmarks)
        self._parsed: dict[str, Override] = {}
        self._groups: dict[str, bool] = {}
        self._templates: dict[tuple, _Composed] = {}  # (shape, options) -> Hydra's composition
        self._bases: dict[Shape, _Composed] = {}  # shape -> the first composition of that shape
        self._variants: dict[tuple, _Composed | None] = {}  # (shape, base lines, group, option) -> None if not separable
        self._fixed_bases: dict[tuple, _Composed] = {}  # (shape, non-separable options) -> the first composition with them
        self._prefetched: set[tuple] = set()  # (shape, base lines) whose variants were composed ahead
        self._asked: dict[tuple, DictConfig] = {}  # (master, overrides) -> the job's config, asked for once
        # note(config) of every job composed, by (master, overrides): the launcher's batch key, so
        # that the jobs of a key can be sent together without composing the whole sweep ahead
        self.note: Callable[[DictConfig], Any] | None = None
        self.noted: dict[tuple, Any] = {}
        self._notes: dict[Any, Any] = {}  # each note once (equal notes of many jobs share one object)
        # with notes, the configs of the jobs checked, pickled, for pickled_config (instead of _asked)
        self._pickled: dict[tuple, bytes] = {}
        self._pickled_bytes = 0
        self._live: dict[tuple, DictConfig] = {}  # per composition, the config pickled_config sets each job's values in

    @classmethod
    def wrap(cls, loader: ConfigLoader, enabled: bool = True) -> ComposingLoader:
        return loader if isinstance(loader, cls) else cls(loader, enabled)

    # --- Hydra's own --------------------------------------------------------------------------------
    def load_configuration(self, *args: Any, **kwargs: Any) -> DictConfig:
        return self.loader.load_configuration(*args, **kwargs)

    def get_search_path(self) -> Any:
        return self.loader.get_search_path()

    def get_sources(self) -> Any:
        return self.loader.get_sources()

    def list_groups(self, parent_name: str) -> Any:
        return self.loader.list_groups(parent_name)

    def get_group_options(self, *args: Any, **kwargs: Any) -> Any:
        return self.loader.get_group_options(*args, **kwargs)

    def compute_defaults_list(self, *args: Any, **kwargs: Any) -> Any:
        return self.loader.compute_defaults_list(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:  # what later Hydra releases add to the interface
        loader = vars(self).get("loader")  # None: not set up yet (copy, unpickling), as any missing attribute
        if loader is None:
            raise AttributeError(name)
        return getattr(loader, name)

    def _hydra(self, master: DictConfig, lines: list[str], options: dict[str, str]) -> tuple[DictConfig, _Composed]:
        hydra_lines = list(master.hydra.overrides.hydra)
        cfg = self.loader.load_sweep_config(master, lines[len(hydra_lines) :])
        self.hydra_compositions += 1
        composed = _Composed(pickle.dumps(cfg), list(lines), dict(options), str(master.hydra.job.config_name), _choices(cfg))
        return cfg, composed

    def _defaults(self, c: _Composed) -> list[tuple]:
        """The defaults list Hydra composed ``c`` from (computed on first use)."""
        if c.defaults is None:
            found = self.loader.compute_defaults_list(c.config_name, list(c.lines), RunMode.RUN)
            c.defaults = [(d.config_path, d.package, d.parent, d.is_self) for d in found.defaults]
        return c.defaults

    # --- the sweep's jobs -------------------------------------------------------------------------
    def load_sweep_config(self, master_config: DictConfig, sweep_overrides: list[str]) -> DictConfig:
        if not self.enabled or OmegaConf.select(master_config, "hydra.searchpath"):
            return self.loader.load_sweep_config(master_config, sweep_overrides)
        # Hydra's sweeper composes every job to check it and drops the config (it changes
        # nothing in it); the launcher then asks for it again: the same config is kept for that
        # second call (a bounded number of them)
        key = (id(master_config), tuple(sweep_overrides))
        if key in self._asked:
            return self._asked.pop(key)
        cfg = self._compose(master_config, sweep_overrides)
        if self.note is not None:
            note = self.note(cfg)
            self.noted[key] = self._notes.setdefault(note, note)
        if self.note is None:
            if len(self._asked) < KEEP_ASKED:
                self._asked[key] = cfg
        elif self._pickled_bytes < KEEP_PICKLED_BYTES and key not in self._pickled:
            # zrp_ga's launcher takes the job pickled (pickled_config) instead of composing it again,
            # at a fifth of the cost; compressed (a config: 23 kB pickled, 6 kB so). Not kept as
            # configs: a thousand of them make every run of the garbage collector slow
            self._pickled[key] = data = zlib.compress(pickle.dumps(cfg), 1)
            self._pickled_bytes += len(data)
        return cfg

    def pickled_config(self, master_config: DictConfig, sweep_overrides: list[str], compose: bool = True) -> bytes | None:
        """``pickle.dumps(load_sweep_config(master_config, sweep_overrides))``, from the
        config kept when the sweeper checked the job, if it was (else None with ``compose=False``)."""
        key = (id(master_config), tuple(sweep_overrides))
        data = self._pickled.pop(key, None)
        if data is not None:
            self._pickled_bytes -= len(data)
            return zlib.decompress(data)
        if not compose:
            return None
        if key in self._asked or not self.enabled or OmegaConf.select(master_config, "hydra.searchpath"):
            return pickle.dumps(self.load_sweep_config(master_config, sweep_overrides))
        return pickle.dumps(self._compose(master_config, sweep_overrides, reuse=True))  # not kept again

    def noted_for(self, master_config: DictConfig, sweep_overrides: list[str], default: Any = None) -> Any:
        """``note(config)`` of the job, noted when it was composed (``default``: not composed yet)."""
        return self.noted.get((id(master_config), tuple(sweep_overrides)), default)

    def _compose(self, master_config: DictConfig, sweep_overrides: list[str], reuse: bool = False) -> DictConfig:
        """The job's config; ``reuse``: for a job composed from a kept composition, one config
        per composition, its values set anew for each job (the caller pickles it at once and
        keeps nothing: a copy of the composition unpickled a job costs more than the pickle)."""
        lines = [*master_config.hydra.overrides.hydra, *sweep_overrides]
        overrides = [self._parse(line) for line in lines]
        shape, options, values = self._classify(overrides)
        key = (shape, tuple(options.items()))
        cfg = None if key in self._templates else self._from_base(master_config, shape, options)
        template = None
        if cfg is not None:  # kept for the jobs with the same options (other values: seeds): put together once
            self._templates[key] = _Composed(pickle.dumps(cfg), list(lines), dict(options), str(master_config.hydra.job.config_name),
                                             _choices(cfg))  # fmt: skip
        else:
            template = self._templates.get(key)  # perhaps composed on the way, as a group's variant
            if template is None:
                cfg, self._templates[key] = self._hydra(master_config, lines, options)
                first = self._bases.setdefault(shape, self._templates[key])
                fixed = self._fixed(master_config, shape, first, options)
                if fixed:
                    self._fixed_bases.setdefault((shape, fixed), self._templates[key])
                return cfg
            cfg = self._live.get(key) if reuse else None
            if cfg is None:
                cfg = pickle.loads(template.data)
            if reuse:  # dropped until this job's values are all set (a value that fails leaves it half set)
                self._live.pop(key, None)
        self._complete(cfg, overrides, values)
        OmegaConf.copy_cache(from_config=master_config, to_config=cfg)
        if reuse and template is not None:
            self._live[key] = cfg
        return cfg

    def _parse(self, line: str) -> Override:
        if line not in self._parsed:
            self._parsed[line] = OverridesParser.create().parse_overrides([line])[0]
        return self._parsed[line]

    def _is_group(self, key: str) -> bool:
        if key not in self._groups:
            parent, _, name = key.rpartition("/")
            self._groups[key] = "." not in key and name in self.loader.list_groups(parent)
        return self._groups[key]

    def _classify(self, overrides: list[Override]) -> tuple[Shape, dict[str, str], list[Override]]:
        """The shape of a job's overrides, its group options and its value overrides."""
        shape: list[tuple[str, ...]] = []
        options: dict[str, str] = {}
        values: list[Override] = []
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
                shape.append(("line", _line(o)))
        return tuple(shape), options, values

    def _from_base(self, master: DictConfig, shape: Shape, options: dict[str, str]) -> DictConfig | None:
        """The first composition of ``shape`` with the subtrees of the groups whose option
        differs put in; None when a group is not separable (see the module docstring)."""
        base = self._bases.get(shape)
        if base is None:
            return None
        self._prefetch(master, shape, base)
        fixed = self._fixed(master, shape, base, options)
        if fixed:  # the first composition with the same options that are not separable, if any
            base = self._fixed_bases.get((shape, fixed))
            if base is None:
                return None
        changed = [self._variant(master, shape, base, g, o) for g, o in options.items() if base.options[g] != o]
        # each with its package (_variant gives None for a variant that is not separable, and a package with any other)
        separable = [(v, v.package) for v in changed if v is not None and v.package is not None]
        if len(separable) < len(changed) or not _disjoint([package for _, package in separable]):
            return None
        cfg = pickle.loads(base.data)
        for variant, package in separable:
            assert variant.config is not None  # _make_variant keeps its composition
            _put(cfg, package, OmegaConf.select(variant.config, package))
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
            self._keep_variant(key, shape, base, self._make_variant(master, shape, base, group, option))
        return self._variants[key]

    def _make_variant(self, master: DictConfig, shape: Shape, base: _Composed, group: str, option: str) -> _Composed:
        """Hydra's composition of ``base``'s overrides with ``group=option``, with the package
        it changes (None: not separable)."""
        lines = [f"{group}={option}" if (s[0] == "group" and s[1] == group) else line for s, line in zip(shape, base.lines)]
        cfg, variant = self._hydra(master, lines, {**base.options, group: option})
        variant.package = _changed_package(base, variant, group, self._defaults)
        if variant.package is not None and not _gives_back(cfg, base, variant.package, group):
            variant.package = None
        variant.config = cfg
        return variant

    def _keep_variant(self, key: tuple, shape: Shape, base: _Composed, variant: _Composed) -> None:
        self._variants[key] = variant if variant.package is not None else None
        self._templates.setdefault((shape, tuple(variant.options.items())), variant)
        if variant.package is None:
            fixed = tuple(sorted((g, o) for g, o in variant.options.items() if base.options[g] != o))
            self._fixed_bases.setdefault((shape, fixed), variant)

    def _prefetch(self, master: DictConfig, shape: Shape, base: _Composed) -> None:
        """Compose, on every core at once, the variants of ``base`` the sweep will ask for: each
        option of each swept group (``hydra.sweeper.params`` and the command line's sweeps)
        other than ``base``'s. Hydra composes one config in about 0.2 s, and a grid's jobs ask
        for their variants one after another; forked processes (Linux) share the loader."""
        if not self.prefetch or (shape, tuple(base.lines)) in self._prefetched:
            return
        self._prefetched.add((shape, tuple(base.lines)))
        todo = [(g, o) for g, o in _swept(master, self._is_group) if g in base.options and o != base.options[g]
                and (shape, tuple(base.lines), g, o) not in self._variants]  # fmt: skip
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
        if len(todo) < 2 or cores < 2 or "fork" not in multiprocessing.get_all_start_methods():
            return
        global _FORKED
        _FORKED = (self, master, shape, base, todo)
        pool = multiprocessing.get_context("fork").Pool(min(cores, len(todo)), initializer=_quiet_child)
        try:
            made = pool.map(_make_in_child, range(len(todo)))
        except Exception:  # composed one at a time, as asked, instead
            return
        finally:
            _FORKED = None
            pool.close()  # the children end on their own: no signal (the app turns SIGTERM into Ctrl-C)
            pool.join()
        for (g, o), variant in zip(todo, made):
            self.hydra_compositions += 1
            self._keep_variant((shape, tuple(base.lines), g, o), shape, base, variant)

    @staticmethod
    def _complete(cfg: DictConfig, overrides: list[Override], values: list[Override]) -> None:
        """What Hydra sets from a job's overrides: the values, ``overrides.task`` and the
        ``override_dirname`` (the choices are set by the caller)."""
        for o in values:  # as Hydra applies a value override
            try:
                OmegaConf.update(cfg, o.key_or_group, o.value(), merge=True)
            except OmegaConfBaseException as ex:
                raise ConfigCompositionException(f"Error merging override {o.input_line}") from ex
        task = [o for o in overrides if not o.is_hydra_override()]
        for k, o in enumerate(task):
            cfg.hydra.overrides.task[k] = o.input_line
        if not OmegaConf.is_interpolation(cfg.hydra.job, "override_dirname"):  # hydra-core 1.3: a value
            names = cfg.hydra.job.config.override_dirname
            cfg.hydra.job.override_dirname = override_dirname(task, names.exclude_keys, names.item_sep, names.kv_sep)


# what a forked process of ComposingLoader._prefetch composes from: the loader, master config, shape, base and (group, option)s
_FORKED: tuple[ComposingLoader, DictConfig, Shape, _Composed, list[tuple[str, str]]] | None = None


def _quiet_child() -> None:
    """In a composing child: the default SIGTERM and no SIGINT (the sweep's process handles
    Ctrl-C; zrp-ga's own handlers, inherited by the fork, would raise KeyboardInterrupt here)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _make_in_child(k: int) -> _Composed:
    assert _FORKED is not None  # set by _prefetch before it forks
    loader, master, shape, base, todo = _FORKED
    return loader._make_variant(master, shape, base, *todo[k])


def _swept(master: DictConfig, is_group: Any) -> list[tuple[str, str]]:
    """The (group, option) pairs a sweep's groups take, from its sweeper's ``params`` and the
    command line's sweep overrides (a choice or range; a glob is left out)."""
    lines = [f"{k}={v}" for k, v in (OmegaConf.select(master, "hydra.sweeper.params") or {}).items()]
    lines += list(master.hydra.overrides.task)
    out = []
    for line in lines:
        try:
            o = OverridesParser.create().parse_overrides([line])[0]
        except Exception:
            continue
        if o.is_sweep_override() and o.value_type is not None and "GLOB" not in o.value_type.name and is_group(o.key_or_group):
            out += [(o.key_or_group, str(v)) for v in o.sweep_string_iterator()]
    return list(dict.fromkeys(out))


def override_dirname(overrides: list[Override], exclude_keys: Any, item_sep: str, kv_sep: str) -> str:
    """``hydra.job.override_dirname`` as Hydra 1.3 computes it: the task overrides but the
    excluded keys, sorted, joined by ``item_sep``, with ``kv_sep`` for ``=`` (Hydra's
    documentation, "Customizing working directory pattern")."""
    lines = sorted(_line(o) for o in overrides if o.key_or_group not in exclude_keys)
    return re.sub("[=]", kv_sep, item_sep.join(lines))


def _line(o: Override) -> str:
    """The line an override was parsed from."""
    assert o.input_line is not None  # Hydra's OverridesParser sets it on every override it parses
    return o.input_line


def _choices(cfg: DictConfig) -> dict[str, Any]:
    """A composition's ``hydra.runtime.choices``, as a dict."""
    choices = OmegaConf.to_container(cfg.hydra.runtime.choices)
    assert isinstance(choices, dict)  # a DictConfig's container is a dict
    return choices  # type: ignore[return-value]  # its keys are the groups' names, str; to_container types them DictKeyType


def _inside(package: str, root: str) -> bool:
    return package == root or package.startswith(root + ".")


def _disjoint(packages: list[str]) -> bool:
    return not any(a is not b and _inside(a, b) for a in packages for b in packages)


def _changed_package(base: _Composed, variant: _Composed, group: str, defaults: Any) -> str | None:
    """The package of ``group``'s option when the two defaults lists (``defaults(composed)``)
    differ only inside it and the choices only in ``group``; else None."""
    if list(base.choices) != list(variant.choices):
        return None
    if any(base.choices[k] != variant.choices[k] for k in base.choices if k != group):
        return None
    old = [d for d in defaults(base) if d[0] == f"{group}/{base.options[group]}"]
    new = [d for d in defaults(variant) if d[0] == f"{group}/{variant.options[group]}"]
    if len(old) != 1 or len(new) != 1 or old[0][1] != new[0][1] or not old[0][1]:
        return None
    package = old[0][1]
    rest = [[d for d in defaults(c) if not (d[1] is not None and _inside(d[1], package))] for c in (base, variant)]
    return package if rest[0] == rest[1] else None


def _gives_back(cfg: DictConfig, base: _Composed, package: str, group: str) -> bool:
    """The composition with ``group``'s option changed equals ``base`` once ``base``'s subtree,
    choice and override lines are put back (an empirical check of separability)."""
    first, other = pickle.loads(base.data), pickle.loads(pickle.dumps(cfg))
    _put(other, package, OmegaConf.select(first, package))
    other.hydra.runtime.choices[group] = base.options[group]
    for k, line in enumerate(first.hydra.overrides.task):
        other.hydra.overrides.task[k] = line
    if not OmegaConf.is_interpolation(first.hydra.job, "override_dirname"):
        other.hydra.job.override_dirname = first.hydra.job.override_dirname
    return OmegaConf.to_yaml(other) == OmegaConf.to_yaml(first)


def _put(cfg: DictConfig, package: str, node: Any) -> None:
    """Replace the subtree at the dotted ``package`` of ``cfg`` by a copy of ``node``, a node
    of the same schema field in another composition."""
    parent, _, leaf = package.rpartition(".")
    target = OmegaConf.select(cfg, parent) if parent else cfg
    target[leaf] = node
