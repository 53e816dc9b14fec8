"""Where a calibration's data reach in joint space, and how far a target lies beyond them
(docs/model.md, section 3.4).

The calibration poses q_k (M, n) (revolute joints in rad, prismatic in m: one metre counts as
one radian, about an arm's reach) span per joint the range ``[min_k q_kj, max_k q_kj]``; in
joint space a target's distance to the nearest calibration pose is compared with the
calibration poses' own leave-one-out nearest distances (their largest, ``gap``: the coarsest
spacing the data have). A target is **outside** when a joint lies beyond its range or its
distance exceeds ``gap``; its ``ratio`` is distance / gap. ``scipy.spatial.cKDTree`` finds the
nearest poses.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]
FILE = "coverage.json"
MOST = 0.5  # a warning when more than this share of the targets lies outside


@dataclasses.dataclass(frozen=True)
class Assessment:
    """Per target: ``outside`` (bool), the joints beyond their ranges (``beyond``, (M, n) bool,
    and how far, ``excess`` (M, n) rad or m), the distance to the nearest calibration pose and
    its ``ratio`` to the coverage's ``gap``."""

    outside: NDArray[np.bool_]
    beyond: NDArray[np.bool_]
    excess: Array
    distance: Array
    ratio: Array

    @property
    def share_outside(self) -> float:
        return float(np.mean(self.outside)) if self.outside.size else 0.0

    def summary(self) -> dict[str, Any]:
        """Share outside, the joints beyond their ranges (share of targets per joint), the
        largest and median distance ratio (``summary.json``)."""
        return {"targets": int(self.outside.size), "share_outside": self.share_outside,
                "share_beyond_range_per_joint": np.mean(self.beyond, axis=0).round(4).tolist() if self.beyond.size else [],
                "distance_ratio": {"median": float(np.median(self.ratio)), "max": float(np.max(self.ratio))} if self.ratio.size else {},
                "extrapolation": bool(self.share_outside > MOST)}  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Coverage:
    """The region calibration poses ``q`` (M, n) cover (module docstring)."""

    q: Array

    @property
    def lower(self) -> Array:
        return self.q.min(axis=0)

    @property
    def upper(self) -> Array:
        return self.q.max(axis=0)

    @property
    def gap(self) -> float:
        """The largest leave-one-out nearest distance among the calibration poses."""
        from scipy.spatial import cKDTree

        q = np.unique(self.q, axis=0)
        if len(q) < 2:
            return 0.0
        d, _ = cKDTree(q).query(q, k=2)
        return float(d[:, 1].max())

    def assess(self, q: ArrayLike) -> Assessment:
        """Where targets q (M, n) lie (module docstring)."""
        from scipy.spatial import cKDTree

        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[1] != self.q.shape[1]:
            raise ValueError(f"coverage: targets of {q.shape[1]} joints, the calibration has {self.q.shape[1]}")
        excess = np.maximum(self.lower - q, 0.0) + np.maximum(q - self.upper, 0.0)
        beyond = excess > 1e-9
        distance = cKDTree(self.q).query(q)[0] if len(q) else np.zeros(0)
        gap = self.gap
        ratio = distance / gap if gap > 0 else np.where(distance > 1e-9, np.inf, 0.0)
        return Assessment(beyond.any(axis=1) | (ratio > 1.0), beyond, excess, distance, ratio)

    def to_dict(self) -> dict[str, Any]:
        return {"joint_ranges": np.column_stack([self.lower, self.upper]).tolist(), "gap": self.gap, "q": self.q.tolist()}

    @classmethod
    def read(cls, run: str | Path) -> Coverage:
        """From a run directory's ``coverage.json`` (or that file)."""
        path = Path(run)
        path = path / FILE if path.is_dir() else path
        return cls(np.array(json.loads(path.read_text())["q"], dtype=float))


def assess_targets(run: str | Path, q: ArrayLike) -> Assessment:
    """For any program (compensation's rows): where joint values q (M, n) (rad, m) lie against
    a finished run's calibration poses (its ``coverage.json``)."""
    return Coverage.read(run).assess(q)
