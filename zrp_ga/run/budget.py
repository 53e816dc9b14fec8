"""The size of a run, estimated before any work: memory and time, from what the problem kind
and the optimiser declare. A run (or a sweep's largest job) whose estimate does not fit the
memory this process may use is refused with one line that gives the estimate, the limit that
binds and the setting to lower, before anything is read or allocated.

What is counted. The problem kind declares its instance's size (``size(robot, **settings)`` in
the kind's module, beside ``build``: :class:`zrp_ga.problems.size.ProblemSize`: genes, what the
instance holds, bytes and seconds per genome evaluated), the optimiser what it holds and
evaluates on a problem of that size (:meth:`zrp_ga.algorithms.Algorithm.size`:
:class:`zrp_ga.algorithms.AlgorithmSize`: the genomes evaluated at once, the evaluations, its
own memory). The estimate is the kind's parts (``poses``, ``validation``, ``parameters``, ...)
and the ``population`` (the genomes evaluated at once, each with what the kind holds per
evaluation, and what the optimiser holds), all times 1.25 for what the sum leaves out
(measured peaks, tracemalloc: 0.9 to 1.3 of the sum on simulated, measured and 200-joint runs,
tests/test_bad_inputs_more.py). A kind that declares nothing (no ``size`` in its module) is
counted as a calibration of the arm's whole genome (6n + 6 genes) on its ``n_poses`` poses
(1 if it has no such setting) and ``n_validation`` validation poses (0), with orientations; an
optimiser that declares nothing as ``population.mu + population.lambda_`` genomes; the estimate
says so (:attr:`Estimate.notes`, in the refusal's line). The time is said, not enforced: a run
estimated to take more than 10 minutes is announced.

The memory this process may use (:func:`memory_limit`) is the least of what the machine has
available (``MemAvailable`` of ``/proc/meminfo``, elsewhere ``os.sysconf``'s free pages), what
the process's address-space and data-segment limits leave (``ulimit -v``, ``ulimit -d``:
``resource.getrlimit`` less the ``VmSize``, ``VmData`` the process maps already and 256 MB
for what its code maps later) and what its
cgroups' memory limits leave (a container's, a cluster job's: cgroup v2 ``memory.max`` less
``memory.current``, v1 ``memory.limit_in_bytes`` less ``memory.usage_in_bytes``, each less the
inactive file pages of ``memory.stat``, which the kernel reclaims before it fails an allocation,
as the kubelet counts a working set; every cgroup from the process's up to the root). The
environment variable ``ZRP_GA_MEMORY`` (``8G``, ``500M``, bytes) replaces all of them, to allow
a run the estimate overrates or to keep a shared machine's runs smaller.

>>> from zrp_ga.algorithms import AlgorithmSize
>>> from zrp_ga.problems.size import calibration
>>> e = estimate(calibration(n=6, genes=42, poses=30, validation=100, rows_per_pose=6), AlgorithmSize(40, 460, 40 * 1272))
>>> round(e.bytes / 1e6, 1), round(e.seconds, 1)
(2.0, 0.2)
"""

from __future__ import annotations

import dataclasses
import importlib
import logging
import math
import os
from collections.abc import Mapping
from pathlib import Path, PurePosixPath
from typing import Any

from zrp_ga.algorithms import AlgorithmSize, evaluations, genomes_bytes
from zrp_ga.problems.size import Lower, ProblemSize, calibration

log = logging.getLogger(__name__)

ENV = "ZRP_GA_MEMORY"
MARGIN = 1.25  # for what the sum leaves out (Python objects, short-lived copies): measured peaks were 0.9-1.3 of it
LONG_S = 600  # a run estimated to take longer is announced
PROC, CGROUP = Path("/proc"), Path("/sys/fs/cgroup")
UNLIMITED = 2**60  # a cgroup v1 limit at least this large is none (the kernel writes 2^63 less a page)
LATER_MAPPED = 256 * 2**20  # address space a run maps after its check (numba's compiler, thread stacks): 110 MB measured


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A run's estimate: ``memory`` (bytes, the margin included) and ``time`` (s) by part, the
    setting that drives each part (``lower``: part -> (config key, what to do)) and ``notes``
    saying what was counted generically (a kind or optimiser that declares no size)."""

    memory: dict[str, float]
    time: dict[str, float]
    lower: dict[str, Lower]
    notes: tuple[str, ...] = ()

    @property
    def bytes(self) -> float:
        return sum(self.memory.values())

    @property
    def seconds(self) -> float:
        return sum(self.time.values())


def estimate(problem: ProblemSize, algorithm: AlgorithmSize, notes: tuple[str, ...] = ()) -> Estimate:
    """The estimate of a run of ``algorithm`` on ``problem`` (module docstring)."""
    memory = dict(problem.held_bytes)
    memory["population"] = algorithm.population * problem.genome_bytes + algorithm.held_bytes
    time = dict(problem.build_s)
    if algorithm.evaluations:
        time["population"] = algorithm.evaluations * (problem.evaluation_s + algorithm.evaluation_s)
    return Estimate({k: MARGIN * v for k, v in memory.items()}, time, {**problem.lower, "population": algorithm.lower}, notes)


# --- what the problem kind and the optimiser declare -----------------------------------------------
def _settings(node: Any) -> dict[str, Any]:
    """A config node's settings (a mapping's items or a dataclass's fields), ``_target_`` left out."""
    if dataclasses.is_dataclass(node):
        items = {f.name: getattr(node, f.name) for f in dataclasses.fields(node)}
    else:
        items = {k: node[k] for k in node}
    return {str(k): v for k, v in items.items() if not str(k).startswith("_")}


def problem_size(node: Any, robot: Any) -> tuple[ProblemSize, tuple[str, ...]]:
    """What the problem kind of config node ``node`` (its ``_target_``) declares for ``robot``:
    ``size(robot, **settings)`` of the kind's module; else the generic count (module
    docstring) and a note saying so."""
    target = str(getattr(node, "_target_", "") or "")
    module = target.rpartition(".")[0]
    try:
        declared = getattr(importlib.import_module(module), "size", None) if module else None
    except ImportError:  # the build names what is missing
        declared = None
    settings = _settings(node)
    if callable(declared):
        try:
            return declared(robot, **settings), ()
        except TypeError as exc:  # a setting its size() does not take (its build would not either)
            from zrp_ga.config import ConfigError

            raise ConfigError(f"problem: {module}.size: {exc}") from None
    genes = _generic_genes(robot.n)
    poses, validation = _count(settings.get("n_poses"), 1), _count(settings.get("n_validation"), 0)
    note = (f"problem kind {module or target!r} declares no size (no size() beside its build): counted as a calibration "
            f"of {genes} genes on {poses} pose(s) and {validation} validation pose(s)")  # fmt: skip
    return calibration(robot.n, genes, poses, validation, 6), (note,)


def _generic_genes(n: int) -> int:
    from zrp_ga.model.layout import Layout

    return Layout(n, base=True, hand=True).size


def _count(value: Any, default: int) -> int:
    try:
        return max(int(value), 0)
    except (TypeError, ValueError):
        return default


def algorithm_size(algorithm: Any, cfg: Any, problem: ProblemSize) -> tuple[AlgorithmSize, tuple[str, ...]]:
    """What ``algorithm`` (built from ``cfg.algorithm``) declares on ``problem``
    (:meth:`zrp_ga.algorithms.Algorithm.size`); else ``population.mu + population.lambda_``
    genomes and a note saying so."""
    declare = getattr(algorithm, "size", None)
    declared = declare(problem) if callable(declare) else None
    if declared is not None:
        return declared, ()
    pop = getattr(cfg, "population", None)
    mu, lam = (_count(getattr(pop, k, None), 1) for k in ("mu", "lambda_"))
    evals = evaluations(getattr(pop, "generations", None), getattr(pop, "max_evals", None), mu, lam)
    note = (f"optimiser {type(algorithm).__module__}.{type(algorithm).__name__} declares no size (no size() method): "
            f"counted as population.mu + population.lambda_ = {mu + lam} genomes")  # fmt: skip
    return AlgorithmSize(mu + lam, evals, genomes_bytes(mu + lam, problem.genes)), (note,)


def of_config(cfg: Any, robot: Any, problem: ProblemSize | None = None, algorithm: Any = None) -> Estimate:
    """The estimate of the run of config ``cfg`` on ``robot`` (a ZRPRobot): its problem kind's
    declared size (``problem``: given instead, for data in memory) and its optimiser's
    (``algorithm``: built already; else built from ``cfg.algorithm`` here, which checks its settings)."""
    notes: tuple[str, ...] = ()
    if problem is None:
        problem, notes = problem_size(cfg.problem, robot)
    if algorithm is None:
        from zrp_ga import config

        algorithm = config.instantiate(cfg.algorithm, "algorithm", root=cfg)
    sized, more = algorithm_size(algorithm, cfg, problem)
    return estimate(problem, sized, notes + more)


def check_config(cfg: Any, robot: Any, available: float | Limit | None = None, problem: ProblemSize | None = None) -> Estimate:
    """:func:`check` the run of ``cfg`` on ``robot`` (:func:`of_config`) before its problem is built."""
    e = of_config(cfg, robot, problem)
    check(e, available)
    return e


# --- the memory this process may use ---------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Limit:
    """Bytes this process may use by one account: ``says`` which (for the refusal's line),
    ``hint`` how to raise it."""

    bytes: float
    says: str
    hint: str = ""


def parse_bytes(text: str) -> float:
    """``8G``, ``500M``, ``64k`` or a number of bytes; ValueError naming ZRP_GA_MEMORY."""
    t = str(text).strip().upper().removesuffix("B").removesuffix("I")
    scale = {"K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}.get(t[-1:], 1)
    try:
        value = float(t[:-1] if scale > 1 else t) * scale
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{ENV}: must be an amount of memory such as 8G or 500M, got {text!r}")
    return value


def memory_limit(environ: Mapping[str, str] | None = None, proc: Path = PROC, cgroup: Path = CGROUP) -> Limit:
    """The memory this process may use, and which account binds (module docstring):
    ``ZRP_GA_MEMORY`` if set, else the least of :func:`limits`; inf when none can be read.
    ``proc``, ``cgroup``: where the kernel's files are (``/proc``, ``/sys/fs/cgroup``)."""
    environ = os.environ if environ is None else environ
    if environ.get(ENV):
        b = parse_bytes(environ[ENV])
        return Limit(b, f"{ENV} allows {_human(b)}", f"or raise {ENV}")
    found = limits(proc, cgroup)
    return min(found, key=lambda lim: lim.bytes) if found else Limit(math.inf, "no memory limit was found")


def available_bytes(environ: Mapping[str, str] | None = None) -> float:
    """Bytes this process may use (:func:`memory_limit`), for other code's estimates."""
    return memory_limit(environ).bytes


def limits(proc: Path = PROC, cgroup: Path = CGROUP) -> list[Limit]:
    """Every account of this process's memory that could be read: the machine's available
    memory, the address-space and data-segment limits, every cgroup memory limit above it."""
    machine = _machine(proc)
    return ([machine] if machine else []) + _rlimits(proc) + _cgroups(proc, cgroup)


def _machine(proc: Path) -> Limit | None:
    b = _fields(proc / "meminfo").get("MemAvailable")
    if b is None:
        try:
            b = float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            return None
    return Limit(b, f"this machine has {_human(b)} available", f"or set {ENV} to allow more")


def _fields(path: Path) -> dict[str, float]:
    """``Name: value kB`` lines (``/proc/meminfo``, ``/proc/self/status``) as bytes."""
    try:
        lines = path.read_text().splitlines()
    except OSError:
        return {}
    out = {}
    for line in lines:
        name, _, rest = line.partition(":")
        parts = rest.split()
        if parts and parts[0].isdigit():
            out[name.strip()] = float(parts[0]) * (1024 if parts[1:2] == ["kB"] else 1)
    return out


def _rlimits(proc: Path) -> list[Limit]:
    """What the soft address-space (``ulimit -v``) and data-segment (``ulimit -d``) limits leave
    beyond what the process maps already (``VmSize``, ``VmData``; 0 where they cannot be read)
    and what the program maps later (``LATER_MAPPED``: VmSize grew by 110 MB from the check to
    the end of a 30-pose run)."""
    try:
        import resource
    except ImportError:  # Windows
        return []
    status = _fields(proc / "self" / "status")
    out = []
    for name, mapped, flag, what in (("RLIMIT_AS", "VmSize", "-v", "address-space"), ("RLIMIT_DATA", "VmData", "-d", "data-segment")):
        if not hasattr(resource, name):
            continue
        soft = resource.getrlimit(getattr(resource, name))[0]
        if soft == resource.RLIM_INFINITY or soft < 0:
            continue
        used = status.get(mapped, 0.0) + LATER_MAPPED
        left = max(soft - used, 0.0)
        out.append(Limit(left, f"the process's {what} limit (ulimit {flag}: {_human(soft)}, {_human(used)} of it mapped by the "
                               f"program) leaves {_human(left)}", f"or raise ulimit {flag}"))  # fmt: skip
    return out


def _cgroups(proc: Path, root: Path) -> list[Limit]:
    """What every memory-limited cgroup of this process leaves, from its own up to the root:
    v2 (``0::PATH``, files under ``root``) and v1 (``N:...memory...:PATH``, under ``root/memory``)."""
    try:
        lines = (proc / "self" / "cgroup").read_text().splitlines()
    except OSError:
        return []
    out = []
    for line in lines:
        number, controllers, path = (line.split(":", 2) + ["", ""])[:3]
        if number == "0" and not controllers:
            base, files = root, ("memory.max", "memory.current", "inactive_file")
        elif "memory" in controllers.split(","):
            base, files = root / "memory", ("memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")
        else:
            continue
        rel = PurePosixPath(path.strip() or "/").relative_to("/")
        for folder in [base / rel, *(base / p for p in rel.parents)]:
            limit = _number(folder / files[0])
            if limit is None or limit >= UNLIMITED:
                continue
            in_use = max((_number(folder / files[1]) or 0.0) - _stat(folder / "memory.stat", files[2]), 0.0)
            left = max(limit - in_use, 0.0)
            out.append(Limit(left, f"the cgroup's memory limit ({folder / files[0]}: {_human(limit)}, {_human(in_use)} in use) "
                                   f"leaves {_human(left)}", "or give the container or job more memory"))  # fmt: skip
    return out


def _number(path: Path) -> float | None:
    """A cgroup file's number; None for ``max``, a missing or unreadable file."""
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    return float(text) if text.isdigit() else None


def _stat(path: Path, key: str) -> float:
    try:
        for line in path.read_text().splitlines():
            name, _, value = line.partition(" ")
            if name == key and value.strip().isdigit():
                return float(value)
    except OSError:
        pass
    return 0.0


# --- the check -------------------------------------------------------------------------------------
def _human(b: float) -> str:
    if not math.isfinite(b):
        return "unlimited"
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= scale:
            return f"{b / scale:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"


def _duration(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.0f} min" if s < 7200 else f"{s / 3600:.1f} h"


def check(e: Estimate, available: float | Limit | None = None, what: str = "the run") -> None:
    """Refuse (ValueError, one line) ``what`` when its memory estimate ``e`` exceeds what this
    process may use (``available``: bytes or a :class:`Limit`; default :func:`memory_limit`),
    naming the estimate, its largest part, the limit that binds and the setting to lower; log
    the estimate otherwise, as a warning when the run will take long."""
    have = memory_limit() if available is None else available if isinstance(available, Limit) else \
        Limit(float(available), f"{_human(float(available))} are available")  # fmt: skip
    need, t = e.bytes, e.seconds
    notes = "".join(f"; {n}" for n in e.notes)
    if need <= have.bytes:
        said = f"{_human(need)} of memory, {have.says}{notes}"
        if t > LONG_S:  # said on the console before the run starts, so that it can be stopped at once
            slowest = max(e.time, key=lambda k: e.time[k])
            log.warning("%s will take about %s (and %s); to go faster: %s", what, _duration(t), said, e.lower[slowest][1])
        else:
            log.debug("size: about %s and %s", _duration(t), said)
        return
    top = max(e.memory, key=lambda k: e.memory[k])
    shares = ", ".join(f"{k} {_human(v)}" for k, v in sorted(e.memory.items(), key=lambda kv: -kv[1]) if v >= 0.01 * need)
    key, advice = e.lower.get(top, (top, f"make {top} smaller"))
    hint = f" ({have.hint})" if have.hint else ""
    raise ValueError(f"{key}: {what} would need about {_human(need)} of memory ({shares}; {_duration(t)}{notes}), "
                     f"{have.says}: {advice}{hint}")  # fmt: skip
