"""Forward kinematics of the ZRP model, as other code calls it (the public contract):
``forward(robot, q) -> (R, p)`` for q (n,) or (M, n), giving (3, 3)/(3,) or (M, 3, 3)/(M, 3);
``forward_batch(u0, b0, R_h0, q)`` a population of parameter sets over all poses in one compiled
call. The functions live in :mod:`zrp_ga.model.kinematics`; the package's own code imports them
from there.

>>> import numpy as np
>>> from zrp_ga import kinematics, robots
>>> R, p = kinematics.forward(robots.get("puma560"), np.zeros(6))
>>> np.round(p, 5).tolist()
[0.4521, -0.15005, 1.10363]
"""

from zrp_ga.model.kinematics import forward, forward_batch

__all__ = ["forward", "forward_batch"]
