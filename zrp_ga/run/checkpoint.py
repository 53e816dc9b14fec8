"""Checkpoints that cannot run code when loaded: arrays in an ``.npz`` file, everything else
(counters, random states, the run's config) as one JSON document inside it, read back with
``allow_pickle=False``. Written atomically (a temporary file, then a rename), so that a kill
while writing leaves the previous checkpoint (a failed write, e.g. a full disk, removes its
temporary file and names the checkpoint); a truncated or foreign file is refused with one
line. The run's config inside it is recorded with a digest of each setting: a checkpoint whose
config was edited since (a setting that changes the run: the population, the problem, the
budget) is refused with one line naming the changed settings, not resumed with its state
from the old settings under a summary of the new ones."""

from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from zrp_ga.core.fileio import replace
from zrp_ga.core.files import regular_file


def save(path: str | Path, state: dict[str, Any]) -> None:
    """Write ``state``: its numpy arrays as arrays, the rest (JSON-able) as JSON."""
    path = Path(path)
    arrays: dict[str, Any] = {k: v for k, v in state.items() if isinstance(v, np.ndarray)}  # Any: to numpy's stubs, ** might hold allow_pickle
    rest = {k: v for k, v in state.items() if not isinstance(v, np.ndarray)}
    if isinstance(rest.get("config"), dict) and "config_digests" not in rest:  # a state read back keeps its own
        rest["config_digests"] = _digests(rest["config"])
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        buffer = io.BytesIO()  # written in one piece: numpy's zip writer seeks back and forth
        np.savez(buffer, __json__=np.array(json.dumps(rest)), **arrays)
        with open(tmp, "wb") as f:
            f.write(buffer.getbuffer())
        replace(tmp, path)
    except BaseException as exc:  # a full disk, a kill: the previous checkpoint stays, the temporary file goes
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and not exc.filename:  # name the file the error is about
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None
        raise


def load(path: str | Path) -> dict[str, Any]:
    """The state :func:`save` wrote; ValueError (one line) if the file is missing or corrupt."""
    path = regular_file(path, "a checkpoint file", missing="no checkpoint there")
    try:
        with np.load(path, allow_pickle=False) as data:
            state: dict[str, Any] = json.loads(str(data["__json__"]))
            state.update({k: data[k] for k in data.files if k != "__json__"})
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable checkpoint, truncated or corrupt ({type(exc).__name__}); "
                         "it cannot be resumed") from None  # fmt: skip
    changed = edited(state)
    if changed:
        from zrp_ga.core.schema import ConfigError

        raise ConfigError(f"{path}: its config was edited since it was written ({', '.join(changed[:6])}{', ...' if len(changed) > 6 else ''} "
                          "changed); a run continues with the settings it started with: put them back, or start a new run")  # fmt: skip
    if isinstance(state.get("random"), list):  # random.setstate wants tuples
        version, internal, gauss = state["random"]
        state["random"] = (version, tuple(internal), gauss)
    return state


UNCHECKED = ("progress", "resume")  # settings that change no result (a resumed run takes them from its command line)


def _digests(config: dict[str, Any]) -> dict[str, str]:
    """Each setting of ``config`` (dotted key) with a digest of its value as JSON."""
    import hashlib

    out: dict[str, str] = {}

    def walk(node: object, key: str) -> None:
        if isinstance(node, dict) and node:
            for k, v in node.items():
                walk(v, f"{key}.{k}" if key else str(k))
        elif key.split(".", 1)[0] not in UNCHECKED:
            out[key] = hashlib.sha256(json.dumps(node, sort_keys=True).encode()).hexdigest()[:16]

    walk(config, "")
    return out


def edited(state: dict[str, Any]) -> list[str]:
    """The settings of the checkpoint ``state``'s config that are not those it was written with
    (none for a checkpoint written before the digests)."""
    recorded, config = state.get("config_digests"), state.get("config")
    if not isinstance(recorded, dict) or not isinstance(config, dict):
        return []
    now = _digests(config)
    return [k for k in [*now, *(k for k in recorded if k not in now)] if now.get(k) != recorded.get(k)]
