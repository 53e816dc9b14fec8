"""Repair: bring genes back into their ranges after variation."""

from __future__ import annotations

import numpy as np

from zrp_ga.core.schema import Repair
from zrp_ga.operators.base import Array, rows


def repair(A: Array, low: Array, up: Array, method: Repair = Repair.clip) -> Array:
    """Bring genes back into [low, up]: ``clip`` to the bound, or ``reflect`` off it (folding
    any distance back into the range). In place; returns A."""
    B = rows(A)
    if Repair(method) is Repair.clip:
        np.maximum(B, low, out=B)  # np.clip with array bounds is three times slower
        np.minimum(B, up, out=B)
    else:
        width = up - low
        y = np.mod(B - low, 2 * width)
        B[:] = low + np.where(y > width, 2 * width - y, y)
    return A
