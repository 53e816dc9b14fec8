"""Objects built from ``_target_`` specs, as ``hydra.utils.instantiate`` builds them, without Hydra.

A spec is a dict, or a dataclass (a section of :mod:`zrp_ga.core.schema`), holding the dotted
name of a callable and its arguments. Its special keys have Hydra's meaning:

- ``_target_``: the callable, found by :func:`pkgutil.resolve_name` (imported as needed);
- ``_args_``: positional arguments (a list); positional arguments given to :func:`instantiate`
  replace them;
- ``_partial_``: true gives a :func:`functools.partial` of the target with the arguments (the
  rest given when it is called); a missing value (``???``) is then left out, so that the
  target's default applies (without ``_partial_`` it is refused);
- ``_recursive_`` (default true): specs nested in the arguments (in dicts, lists and dataclass
  fields) are built first, depth first, each with its own keys; false: the arguments are passed
  as they are.

Arguments are passed as plain values: dicts, lists, and dataclass instances for dataclasses
(Hydra's ``_convert_: object``; a ``_convert_`` key is ignored). Keyword arguments given to
:func:`instantiate` go to the target as they are (Hydra merges them into the config first, which
would turn a dataclass among them, a robot, into a config). An exception the target raises is
raised as it is; a spec that cannot be built (no ``_target_``, one that cannot be imported or is
not callable, a bad flag, a missing value) is a :class:`TargetError`.

Written by hand rather than calling ``hydra.utils.instantiate`` because the run layer builds
every run's robot, problem and optimiser from the typed config (:mod:`zrp_ga.core.schema`), and
Hydra stays at the edge: the command line, the launcher and the API compose configs with it, the
layers below import neither Hydra nor OmegaConf. ``hydra.utils.instantiate`` also takes
OmegaConf configs only: it would turn each spec into one (a copy and a resolution per run, which
a sweep of short runs pays per job). ``tests/test_targets.py`` checks this module against it on
every option of every config group.
"""

from __future__ import annotations

import dataclasses
import functools
import pkgutil
from collections.abc import Callable, Mapping
from typing import Any

from zrp_ga.core.schema import MISSING, ConfigError, setting  # MISSING: a value not given (OmegaConf's mark)

SPECIAL = ("_target_", "_args_", "_partial_", "_recursive_", "_convert_")


class TargetError(Exception):
    """A spec that cannot be built; the message says why (not the target's own errors)."""


def instantiate(spec: Any, *args: Any, _partial_: bool | None = None, _recursive_: bool | None = None, **kwargs: Any) -> Any:
    """The object ``spec`` describes: its target called with its arguments (module docstring),
    ``args`` and ``kwargs``; ``_partial_`` and ``_recursive_`` replace the spec's own. None for
    a None spec."""
    if spec is None:
        return None
    node = _entries(spec)
    if node is None or "_target_" not in node:
        raise TargetError(f"not a spec to build: a dict or dataclass with _target_, got {spec!r}")
    return _build(node, args, kwargs, _partial_, _recursive_)


def create(spec: Any, key: str, **kwargs: Any) -> Any:
    """The object of the config's spec ``spec`` at ``key`` (``robot``, ``problem``,
    ``algorithm``): :func:`instantiate` as a partial (a missing setting takes the target's
    default), called with ``kwargs``; the user's mistakes as one line: a ValueError or OSError of
    the target raised as itself, any other failure a ConfigError naming ``key``. Running out of
    memory is no mistake in the spec: a MemoryError is raised as itself, for the caller's one
    line about memory (not "problem: ...: MemoryError"); resources that are OSErrors (a full
    disk, too many open files) are raised as themselves already."""
    try:
        return instantiate(spec, _partial_=True)(**kwargs)
    except (ValueError, OSError, MemoryError):
        raise
    except TargetError as exc:
        raise ConfigError(f"{key}: {exc}") from None
    except Exception as exc:
        raise ConfigError(f"{key}: {setting(spec, '_target_')}: {type(exc).__name__}: {exc}") from None


def is_spec(value: Any) -> bool:
    """Whether ``value`` is a spec :func:`instantiate` builds (a dict or dataclass with ``_target_``)."""
    node = _entries(value) if isinstance(value, Mapping) or dataclasses.is_dataclass(value) else None
    return node is not None and "_target_" in node


@functools.cache
def locate(name: str) -> Callable[..., Any]:
    """The callable of the dotted ``name`` (``package.module.function``, ``module.Class``)."""
    if not isinstance(name, str) or not name:
        raise TargetError(f"_target_: must be the dotted name of a callable, got {name!r}")
    try:
        obj = pkgutil.resolve_name(name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise TargetError(f"cannot import {name!r} ({type(exc).__name__}: {exc})") from None
    if not callable(obj):
        raise TargetError(f"{name!r} is not callable (a {type(obj).__name__})")
    return obj


def _entries(spec: Any) -> dict[str, Any] | None:
    """A spec's keys and values (a dataclass's fields); None for anything else."""
    if isinstance(spec, Mapping):
        return dict(spec)
    if dataclasses.is_dataclass(spec) and not isinstance(spec, type):
        return {f.name: getattr(spec, f.name) for f in dataclasses.fields(spec)}
    return None


def _build(node: dict[str, Any], args: tuple, kwargs: dict[str, Any], partial: bool | None, recursive: bool | None) -> Any:
    target = locate(node["_target_"])
    partial = node.get("_partial_", False) if partial is None else partial
    recursive = node.get("_recursive_", True) if recursive is None else recursive
    for flag, value in (("_partial_", partial), ("_recursive_", recursive)):
        if not isinstance(value, bool):
            raise TargetError(f"{flag}: must be true or false, got {value!r}")
    given = node.get("_args_", ())
    if not isinstance(given, (list, tuple)):
        raise TargetError(f"_args_: must be a list of positional arguments, got {given!r}")
    positional = list(args) if args else [_nested(a, recursive) for a in given]
    settings = {}
    for key, value in node.items():
        if key in SPECIAL:
            continue
        if isinstance(value, str) and value == MISSING:
            if partial:
                continue
            raise TargetError(f"{key}: has no value (???), which {node['_target_']} needs")
        settings[key] = _nested(value, recursive)
    settings.update(kwargs)
    return functools.partial(target, *positional, **settings) if partial else target(*positional, **settings)


def _nested(value: Any, recursive: bool) -> Any:
    """An argument as passed: with ``recursive``, the specs in it built and its containers copied."""
    if not recursive:
        return value
    if is_spec(value):
        return instantiate(value)
    if isinstance(value, Mapping):
        return {k: _nested(v, True) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_nested(v, True) for v in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.replace(value, **{f.name: _nested(getattr(value, f.name), True) for f in dataclasses.fields(value)})
    return value
