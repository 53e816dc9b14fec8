"""What the runs of one process share: the one place that holds anything between runs.

Building a problem instance (a robot, its simulated or measured data) costs more than many
small runs, and the identifiability and the floor of an instance cost an SVD and an LM run: a
sweep's jobs in one worker process, and a single run's check and run, take them from
:data:`CACHE` by the instance's key (its resolved robot and problem settings and the seed, as
JSON: instances are pure functions of it). Nothing else is kept between runs.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

MAX_INSTANCES = 8


@dataclasses.dataclass
class Cache:
    """The last few problem instances built, and each instance's identifiability and floor."""

    instances: dict[str, Any] = dataclasses.field(default_factory=dict)  # key -> zrp_ga.problems.Task
    diagnostics: dict[str, dict] = dataclasses.field(default_factory=dict)  # key -> summary.diagnostics' figures
    floors: dict[str, dict] = dataclasses.field(default_factory=dict)  # key -> summary.floor's figures

    def instance(self, key: str, build: Callable[[], Any]) -> Any:
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
