"""Speed of the pose-cost kernels against the machine's floating-point peak, in one run.

1. The peak: a compiled micro-benchmark (LLVM IR through llvmlite, numba's own compiler) of
   independent fused multiply-add chains, ``CHAINS`` vector accumulators (more than the 2 FMA
   ports x 4 cycles latency of current x86 cores, so latency is hidden) at every SIMD width the
   host supports (128, 256, 512 bits), float64 and float32. One core.
2. Each kernel on a population of P PUMA 560 parameter sets over M poses (default 200 x 30, a
   generation of the 30-pose problem), full-pose cost: pose evaluations per second, GFLOP/s from
   the hand-counted flops per pose (``flops_per_pose``) and the % of the measured peak; the
   GA's whole fitness (``CalibrationProblem.costs``: genomes to parameters, unit rows, norm)
   with each kernel; plain Python loops of ``forward()``; the ratios to zrp_ga 0.1's kernel
   (a copy of it is below) and to the Python loop.
3. Two threads against one over population sizes and pose counts.

Every figure is the median of repeated calls, the candidates interleaved (one call of each in
turn) so that the load of other processes falls on all of them alike; single-thread calls are
timed in the thread's CPU time (time other processes hold the core does not count), calls with
threads in wall time. Prints a Markdown table
and writes it to experiments/results/bench_kinematics.md. Run:

    python experiments/bench_kinematics.py [--population 200] [--poses 30] [--seconds 2]
"""

from __future__ import annotations

import argparse
import ctypes
import functools
import os
import platform
import time
from pathlib import Path

import llvmlite
import llvmlite.binding as llvm
import numba
import numpy as np

from zrp_ga.io import presets
from zrp_ga.model import kinematics
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements

OUT = Path(__file__).resolve().parent / "results" / "bench_kinematics.md"
os.environ["ZRP_GA_KERNELS"] = "compiled"  # the compiled kernels even for small calls (not their numpy twins)
CHAINS = 10  # independent accumulators in the peak benchmark


# --- 1. the peak ------------------------------------------------------------------------------

def _fma_ir(lanes: int, ftype: str) -> str:
    """LLVM IR of ``fma_loop(n, out)``: n iterations of CHAINS independent vector FMAs x = x a + b."""
    vt, name = f"<{lanes} x {ftype}>", f"v{lanes}{'f64' if ftype == 'double' else 'f32'}"
    splat = lambda hexval: "<" + ", ".join([f"{ftype} {hexval}"] * lanes) + ">"
    a, b, one = splat("0x3FEFFFFFE0000000"), splat("0x3E7AD7F2A0000000"), splat("0x3FF0000000000000")
    lines = [f"declare {vt} @llvm.fma.{name}({vt}, {vt}, {vt})", "define void @fma_loop(i64 %n, ptr %out) {",
             "entry:", "  br label %loop", "loop:", "  %i = phi i64 [0, %entry], [%i1, %loop]"]
    lines += [f"  %x{k} = phi {vt} [{one}, %entry], [%y{k}, %loop]" for k in range(CHAINS)]
    lines += [f"  %y{k} = call {vt} @llvm.fma.{name}({vt} %x{k}, {vt} {a}, {vt} {b})" for k in range(CHAINS)]
    lines += ["  %i1 = add i64 %i, 1", "  %c = icmp ult i64 %i1, %n", "  br i1 %c, label %loop, label %done", "done:"]
    lines += ["  %s0 = fadd " + vt + " %y0, %y1"] + [f"  %s{k} = fadd {vt} %s{k - 1}, %y{k + 1}" for k in range(1, CHAINS - 1)]
    lines += [f"  store {vt} %s{CHAINS - 2}, ptr %out, align 4", "  ret void", "}"]
    return "\n".join(lines)


_ENGINES = []  # the JIT engines own their code: kept alive for the run


def _fma_function(lanes: int, ftype: str):
    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    machine = llvm.Target.from_default_triple().create_target_machine(
        cpu=llvm.get_host_cpu_name(), features=llvm.get_host_cpu_features().flatten(), opt=2
    )
    module = llvm.parse_assembly(_fma_ir(lanes, ftype))
    engine = llvm.create_mcjit_compiler(module, machine)
    engine.finalize_object()
    _ENGINES.append((engine, machine, module))
    return ctypes.CFUNCTYPE(None, ctypes.c_int64, ctypes.c_void_p)(engine.get_function_address("fma_loop"))


def simd_widths() -> list[int]:
    """Vector widths in bits with FMA on this host."""
    features = llvm.get_host_cpu_features()
    widths = [128] if features.get("fma") else []
    widths += [256] if features.get("fma") and features.get("avx") else []
    widths += [512] if features.get("avx512f") else []
    return widths


def fma_call(bits: int, width: int) -> tuple:
    """A call of about 1 ms of the FMA micro-benchmark and the flops it does (an FMA counts 2)."""
    lanes, ftype = width // bits, "double" if bits == 64 else "float"
    fn, out = _fma_function(lanes, ftype), np.zeros(lanes, np.float64 if bits == 64 else np.float32)
    n = 1_000_000 * 128 // width
    return functools.partial(fn, n, out.ctypes.data), 2 * lanes * CHAINS * n


# --- 2. the kernels ---------------------------------------------------------------------------

def flops_per_pose(kernel: str, n: int) -> int:
    """Floating-point operations of one pose evaluation with full-pose cost (an FMA counts 2).

    Per pose 54 for the residual: position 3 subtractions, 3 weights, 3 squares and 3 additions
    (12); orientation 6 elements of R_meas R_h^T at 5 each, 3 subtractions, 3 halvings, 3 squares
    and 3 additions (42).
    0.1's kernel and ``rodrigues``: per joint Rodrigues on 4 vectors, 30 each (u . x: 5, times
    v: 1; per component 8: cross-product component 3, times s 1, c x 1, d u 1, two additions),
    and the position's ``+= b + t u`` 9: 129 n + 54 (828 for n = 6).
    ``matrix`` and ``float32``: R(q, u) 21 (v u: 3, s u: 3, three products of v u 3, diagonal
    6, off-diagonal 6), the product R_{i-1} R(q_i) 45, b~ = b + t u 6, p += R b~ 18: 90 per
    joint; the first joint 27 (R(q_1) and b~ only), the end 63 (p += R_n b0_{n+1} 18, R_n R_h0
    45): 90 n + 54 (594 for n = 6, of which float32 does 540 in float32).
    """
    return 129 * n + 54 if kernel in ("0.1", "rodrigues") else 90 * n + 54


@numba.njit
def _residual_kernel_01(U, B, H, c, s, t, p_meas, wp, R_meas, use_rot, out):  # pragma: no cover
    """zrp_ga 0.1's pose-cost kernel, verbatim, for the comparison (its chain is kinematics._chain)."""
    P = U.shape[2]
    X = np.empty((12, P))
    out[:, :] = 0.0
    for m in range(c.shape[0]):
        kinematics._chain(U, B, H, c[m], s[m], t[m], X)
        for p in range(P):
            ex = (p_meas[m, 0] - X[0, p]) * wp[m, 0]
            ey = (p_meas[m, 1] - X[1, p]) * wp[m, 1]
            ez = (p_meas[m, 2] - X[2, p]) * wp[m, 2]
            out[1, p] += ex * ex + ey * ey + ez * ez
        if use_rot:
            Rm = R_meas[m]
            for p in range(P):
                w21 = Rm[2, 0] * X[4, p] + Rm[2, 1] * X[7, p] + Rm[2, 2] * X[10, p]
                w12 = Rm[1, 0] * X[5, p] + Rm[1, 1] * X[8, p] + Rm[1, 2] * X[11, p]
                w02 = Rm[0, 0] * X[5, p] + Rm[0, 1] * X[8, p] + Rm[0, 2] * X[11, p]
                w20 = Rm[2, 0] * X[3, p] + Rm[2, 1] * X[6, p] + Rm[2, 2] * X[9, p]
                w10 = Rm[1, 0] * X[3, p] + Rm[1, 1] * X[6, p] + Rm[1, 2] * X[9, p]
                w01 = Rm[0, 0] * X[4, p] + Rm[0, 1] * X[7, p] + Rm[0, 2] * X[10, p]
                dx = 0.5 * (w21 - w12)
                dy = 0.5 * (w02 - w20)
                dz = 0.5 * (w10 - w01)
                out[0, p] += dx * dx + dy * dy + dz * dz


def medians(candidates: dict, seconds: float, clock=time.thread_time) -> dict[str, float]:
    """Median seconds per call of each candidate, calls interleaved for about ``seconds`` in all.
    ``clock``: the calling thread's CPU time by default, so that the time other processes hold
    the core does not count (this machine is shared); wall time for calls that use threads."""
    for fn in candidates.values():
        fn()
    times: dict[str, list[float]] = {name: [] for name in candidates}
    end = time.perf_counter() + seconds
    while time.perf_counter() < end or len(times[next(iter(times))]) < 5:
        for name, fn in candidates.items():
            t0 = clock()
            fn()
            times[name].append(clock() - t0)
    return {name: float(np.median(t)) for name, t in times.items()}


def population(P: int, M: int, seed: int = 0):
    """P PUMA 560 parameter sets (axes +-0.01, body vectors +-0.5 mm), M poses measured on the nominal arm."""
    rng = np.random.default_rng(seed)
    robot = presets.get("puma560")
    u0 = robot.u0 + rng.uniform(-0.01, 0.01, size=(P, 6, 3))
    u0 /= np.linalg.norm(u0, axis=-1, keepdims=True)
    b0 = robot.b0 + rng.uniform(-5e-4, 5e-4, size=(P, 7, 3))
    q = rng.uniform(-np.pi, np.pi, size=(M, 6))
    R_meas, p_meas = kinematics.forward(robot, q)
    return robot, u0, b0, q, p_meas, R_meas


def kernel_calls(P: int, M: int) -> dict:
    """The candidates of table 2: name -> (call, kernel whose flops it does, pose evaluations per call)."""
    robot, u0, b0, q, p_meas, R_meas = population(P, M)
    U, B, H = kinematics._population(u0, b0, robot.R_h0)
    terms = kinematics.joint_terms(q, robot.prismatic)
    out = np.empty((2, P))
    old = functools.partial(_residual_kernel_01, U, B, H, *terms, p_meas, np.ones((M, 3)), R_meas, True, out)
    calls = {"0.1 kernel (copied here)": (old, "0.1", P * M)}
    for kernel in kinematics.KERNELS:
        fn = functools.partial(kinematics.residual_sums_unchecked, U, B, H, terms, p_meas, R_meas, kernel=kernel)
        calls[f"`{kernel}`"] = (fn, kernel, P * M)
    problem = CalibrationProblem(robot, Measurements(q, p_meas, R_meas), Layout(6), -np.ones(36), np.ones(36), cost="nonlinear")
    genomes = np.concatenate([(u0 - robot.u0).reshape(P, -1), (b0 - robot.b0)[:, 1:].reshape(P, -1)], axis=1)
    calls["GA fitness, 0.1 kernel"] = (functools.partial(_fitness, problem, genomes, _sums_01), "0.1", P * M)
    for kernel in kinematics.KERNELS:
        sums = functools.partial(kinematics.residual_sums_unchecked, kernel=kernel)
        calls[f"GA fitness, `{kernel}`"] = (functools.partial(_fitness, problem, genomes, sums), kernel, P * M)
    members = [robot.replace(u0=u0[k], b0=b0[k], normalize=True) for k in range(P)]
    calls["Python loop of forward(), one call per parameter set"] = (functools.partial(_loop_members, members, q, p_meas, R_meas), None, P * M)
    few = members[:10]
    calls["Python loop of forward(), one call per set and pose"] = (functools.partial(_loop_poses, few, q, p_meas, R_meas), None, len(few) * M)
    return calls


def _sums_01(U, B, H, terms, p_meas, R_meas, weights=None):
    """0.1's ``residual_sums_unchecked``."""
    out, M = np.empty((2, U.shape[2])), p_meas.shape[0]
    R = R_meas if R_meas is not None else np.zeros((M, 3, 3))
    _residual_kernel_01(U, B, H, *terms, p_meas, np.ones((M, 3)) if weights is None else weights, R, R_meas is not None, out)
    return out


def _fitness(problem: CalibrationProblem, genomes: np.ndarray, sums) -> None:
    """``problem.costs`` with ``sums`` in place of ``kinematics.residual_sums_unchecked``."""
    default = kinematics.residual_sums_unchecked
    kinematics.residual_sums_unchecked = sums
    try:
        problem.costs(genomes)
    finally:
        kinematics.residual_sums_unchecked = default


def _loop_members(members, q, p_meas, R_meas) -> None:
    for member in members:
        R, p = kinematics.forward(member, q)
        np.sum((p_meas - p) ** 2), np.sum((R_meas - R) ** 2)


def _loop_poses(members, q, p_meas, R_meas) -> None:
    for member in members:
        for m in range(q.shape[0]):
            R, p = kinematics.forward(member, q[m])
            np.sum((p_meas[m] - p) ** 2), np.sum((R_meas[m] - R) ** 2)


def measure(P: int, M: int, seconds: float) -> tuple[dict, dict, dict]:
    """Peaks {width: {bits: GFLOP/s}}, the kernel candidates and their pose evaluations per
    second, all timed in one interleaved loop so that they share the machine's load."""
    calls = kernel_calls(P, M)
    peak_calls = {(w, bits): fma_call(bits, w) for w in simd_widths() for bits in (64, 32)}
    candidates = {name: fn for name, (fn, _, _) in calls.items()} | {key: fn for key, (fn, _) in peak_calls.items()}
    t = medians(candidates, seconds * len(calls))
    peaks: dict = {}
    for (w, bits), (_, flops) in peak_calls.items():
        peaks.setdefault(w, {})[bits] = flops / t[(w, bits)] / 1e9
    return peaks, calls, {name: calls[name][2] / t[name] for name in calls}


def kernel_table(calls: dict, rate: dict, peaks: dict) -> list[str]:
    base, loop = rate["0.1 kernel (copied here)"], rate["Python loop of forward(), one call per set and pose"]
    widest = max(peaks)
    rows = [f"| what | M pose evaluations/s | flops/pose | GFLOP/s | % of peak ({widest}-bit) | % of peak (256-bit) | x 0.1 kernel | x Python loop |",
            "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, (_, kernel, _) in calls.items():
        cells = [name, f"{rate[name] / 1e6:.3f}" if rate[name] < 1e6 else f"{rate[name] / 1e6:.1f}"]
        if kernel is None:
            cells += ["", "", "", ""]
        else:
            bits = 32 if kernel == "float32" else 64
            flops = flops_per_pose(kernel, 6)
            gflops = rate[name] * flops / 1e9
            cells += [str(flops), f"{gflops:.1f}", f"{100 * gflops / peaks[widest][bits]:.0f}",
                      f"{100 * gflops / peaks[256][bits]:.0f}" if 256 in peaks else ""]
        cells += [f"{rate[name] / base:.2f}", f"{rate[name] / loop:.0f}"]
        rows.append("| " + " | ".join(cells) + " |")
    return rows


# --- 3. threads -------------------------------------------------------------------------------

def thread_table(seconds: float) -> list[str]:
    rows = ["| P | M | " + " | ".join(f"`{k}` 1 thread, us | `{k}` x 2 threads" for k in kinematics.KERNELS) + " |",
            "|---:|---:|" + "---:|---:|" * len(kinematics.KERNELS)]
    for P in (20, 50, 200, 1000):
        for M in (1, 30):
            robot, u0, b0, q, p_meas, R_meas = population(P, M)
            U, B, H = kinematics._population(u0, b0, robot.R_h0)
            terms = kinematics.joint_terms(q, robot.prismatic)
            cells = [str(P), str(M)]
            for kernel in kinematics.KERNELS:
                call = functools.partial(kinematics.residual_sums_unchecked, U, B, H, terms, p_meas, R_meas, kernel=kernel)
                t = medians({1: functools.partial(call, threads=1), 2: functools.partial(call, threads=2)}, seconds, time.perf_counter)
                cells += [f"{t[1] * 1e6:.0f}", f"{t[1] / t[2]:.2f}"]
            rows.append("| " + " | ".join(cells) + " |")
    return rows


# --- the report -------------------------------------------------------------------------------

def cpu_name() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown cpu"


def machine() -> str:
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load = " / ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (f"{cpu_name()} ({llvm.get_host_cpu_name()}), {cores} cores usable, load average {load} at the start; "
            f"Python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
            f"llvmlite {llvmlite.__version__}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--poses", type=int, default=30)
    parser.add_argument("--seconds", type=float, default=2.0, help="time per candidate")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    P, M = args.population, args.poses
    lines = ["# Pose-cost kernels against the machine's peak\n", f"Machine: {machine()}.",
             f"Command: `python experiments/bench_kinematics.py --population {P} --poses {M} --seconds {args.seconds}`."]
    if os.environ.get("NUMBA_CPU_FEATURES"):
        lines.append(f"NUMBA_CPU_FEATURES set: `{os.environ['NUMBA_CPU_FEATURES'][-60:]}` (last 60 characters).")
    peaks, calls, rate = measure(P, M, args.seconds)
    lines += ["", "## 1. FMA peak of one core (GFLOP/s; calls of 1 ms interleaved with those of table 2)", "",
              "| SIMD width | float64 | float32 |", "|---:|---:|---:|"]
    lines += [f"| {w} bit | {p[64]:.1f} | {p[32]:.1f} |" for w, p in peaks.items()]
    lines += ["", f"## 2. Pose evaluations: {P} PUMA 560 parameter sets x {M} poses, full-pose cost, one thread", ""]
    lines += kernel_table(calls, rate, peaks)
    lines += ["", "float32 rows against the float32 peak; flops per pose counted by hand (`flops_per_pose`); "
              "the fitness rows count the kernel's flops only. numba's code uses 256-bit vectors on this "
              "CPU unless told otherwise (LLVM's `prefer-256-bit` tuning for AVX-512 cores).",
              "", "## 3. Two threads against one (wall time: median microseconds per call with one thread; speed-up with two)", ""]
    lines += thread_table(args.seconds / 4)
    text = "\n".join(lines) + "\n"
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)


if __name__ == "__main__":
    main()
