"""What the runs of one process share: the one place that holds anything between runs.

Building a problem instance (a robot, its simulated or measured data) costs more than many
small runs, and the identifiability and the floor of an instance cost an SVD and an LM run: a
sweep's jobs in one worker process, and a single run's check and run, take them from
:data:`CACHE` by the instance's key (its resolved robot and problem settings and the seed, as
JSON: instances are pure functions of it). Nothing else is kept between runs.
:func:`few_collections` sets the process's garbage collector for work that makes many objects.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from zrp_ga.problems import Task

MAX_INSTANCES = 8


@dataclasses.dataclass
class Cache:
    """The last few problem instances built, and each instance's identifiability and floor."""

    instances: dict[str, Task] = dataclasses.field(default_factory=dict)  # key -> the problem instance
    diagnostics: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)  # key -> summary.diagnostics' figures
    floors: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)  # key -> summary.floor's figures

    def instance(self, key: str, build: Callable[[], Task]) -> Task:
        """The instance of ``key``, built by ``build()`` the first time."""
        if key not in self.instances:
            self.instances[key] = build()
            while len(self.instances) > MAX_INSTANCES:
                del self.instances[next(iter(self.instances))]
        return self.instances[key]

    def clear(self) -> None:
        for d in (self.instances, self.diagnostics, self.floors):
            d.clear()


CACHE = Cache()


@contextlib.contextmanager
def few_collections(freeze_older: bool = False) -> Iterator[None]:
    """Python's cyclic garbage collector run less often inside (work making many objects and
    little garbage: a run's imports and config, a batch's configs), and with ``freeze_older``
    not over the objects that were there before (Hydra's, numpy's, scipy's: each full collection
    goes over all of them), unless the process froze its objects itself. The settings are
    restored after, also on an exception. Nothing a run computes depends on it."""
    import gc

    frozen = freeze_older and gc.get_freeze_count() == 0
    if frozen:
        gc.freeze()
    before = gc.get_threshold()
    gc.set_threshold(max(before[0], 20_000), *before[1:])
    try:
        yield
    finally:
        gc.set_threshold(*before)
        if frozen:
            gc.unfreeze()
