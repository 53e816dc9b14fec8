"""Pose evaluations per second: batched forward kinematics plus pose cost, against plain loops.

A population of 200 PUMA 560 parameter sets over 50 poses (10,000 pose evaluations per call),
full-pose cost (orientation and position residuals): the compiled kernel alone, and the GA's
whole fitness function (genomes to parameters, axes normalised, unit-length rows, norm). One core: the compiled kernel is serial
and BLAS is not involved. Run:

    python experiments/bench_kinematics.py [--population 200] [--poses 50] [--seconds 3]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from zrp_ga import kinematics, robots
from zrp_ga.problem import CalibrationProblem, Layout, Measurements


def rate(fn, evaluations: int, seconds: float) -> float:
    """Pose evaluations per second of ``fn``: the median of timed calls for ``seconds`` after a
    warm-up (the median, not the best: single calls on this machine vary by a factor 1.5)."""
    fn()
    times = []
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return evaluations / float(np.median(times))


def cpu_name() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown cpu"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--poses", type=int, default=50)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    robot = robots.get("puma560")
    P, M = args.population, args.poses
    u0 = robot.u0 + rng.uniform(-0.01, 0.01, size=(P, 6, 3))
    b0 = robot.b0 + rng.uniform(-5e-4, 5e-4, size=(P, 7, 3))
    q = rng.uniform(-np.pi, np.pi, size=(M, 6))
    R_meas, p_meas = kinematics.forward(robot, q)
    members = [robot.replace(u0=u0[k], b0=b0[k], normalize=True) for k in range(P)]

    def batched():
        kinematics.residual_sums(u0, b0, robot.R_h0, q, p_meas, R_meas)

    problem = CalibrationProblem(
        robot, Measurements(q, p_meas, R_meas), Layout(6), -np.ones(36), np.ones(36), cost="nonlinear"
    )
    genomes = np.concatenate([(u0 - robot.u0).reshape(P, -1), (b0 - robot.b0)[:, 1:].reshape(P, -1)], axis=1)

    def fitness():
        problem.costs(genomes)

    def loop_individuals():
        for member in members:
            R, p = kinematics.forward(member, q)
            np.sum((p_meas - p) ** 2), np.sum((R_meas - R) ** 2)

    def loop_poses():
        for member in members[:20]:
            for m in range(M):
                R, p = kinematics.forward(member, q[m])
                np.sum((p_meas[m] - p) ** 2), np.sum((R_meas[m] - R) ** 2)

    print(f"machine: {cpu_name()} ({platform.machine()}), python {platform.python_version()}")
    print(f"population {P} x {M} poses = {P * M} pose evaluations per call")
    print(f"batched forward + pose cost:            {rate(batched, P * M, args.seconds) / 1e6:8.2f} M pose evaluations/s")
    print(f"the GA's fitness, CalibrationProblem.costs: {rate(fitness, P * M, args.seconds) / 1e6:8.2f} M pose evaluations/s")
    print(f"loop of forward(), one call per member: {rate(loop_individuals, P * M, args.seconds) / 1e6:8.3f} M pose evaluations/s")
    print(f"loop of forward(), one call per pose:   {rate(loop_poses, 20 * M, args.seconds) / 1e6:8.3f} M pose evaluations/s")


if __name__ == "__main__":
    main()
