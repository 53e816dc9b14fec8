"""A batch of a sweep's jobs run in one process (minimal: one after another, each with Hydra's
``run_job`` as ``_workers`` runs it)."""

from __future__ import annotations

from collections.abc import Sequence

from hydra.core.utils import JobReturn
from hydra.types import HydraContext, TaskFunction


def run_batch(jobs: Sequence[tuple[int, bytes]], hydra_context: HydraContext, task_function: TaskFunction) -> list[JobReturn]:
    """``jobs``: (job number, pickled job config) pairs; their returns in the same order."""
    from ._workers import _run_job

    return [_run_job(idx, data, hydra_context, task_function) for idx, data in jobs]
