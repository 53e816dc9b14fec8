"""The error model of the ZRP parameters, as other code calls it (the public contract):
``error_jacobian(robot, q)`` is the (6 + n, 6n) Jacobian of one pose (Eq. 21-27) and, for q of
shape (M, n), the stacked (6M + n, 6n) form; ``pose_error`` the measured pose error. The
functions live in :mod:`zrp_ga.model.error_model`; the package's own code imports them from
there.

>>> import numpy as np
>>> from zrp_ga import error_model, robots
>>> error_model.error_jacobian(robots.get("puma560"), np.zeros((3, 6))).shape
(24, 36)
"""

from zrp_ga.model.error_model import error_jacobian, identifiability, pose_error

__all__ = ["error_jacobian", "identifiability", "pose_error"]
