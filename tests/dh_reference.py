"""An independent homogeneous-transform DH chain, written for the tests only."""

import numpy as np


def _A_std(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def _A_mdh(theta, d, a_prev, alpha_prev):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha_prev), np.sin(alpha_prev)
    return np.array(
        [[ct, -st, 0, a_prev], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]]
    )


def _Ry(beta):
    c, s = np.cos(beta), np.sin(beta)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])


def dh_fk(table, q, modified=False):
    """End-effector 4x4 transform of a (modified) DH table at joint values q. A ``beta`` entry
    (Hayati's tilt about y) adds ``Ry(beta)`` after ``Rx(alpha)``: ``A_std Ry(beta)`` for DH,
    ``Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`` for modified DH."""
    T = np.eye(4)
    offset = table.get("offset", np.zeros(len(table["d"])))
    beta = table.get("beta", np.zeros(len(table["d"])))
    for i, qi in enumerate(q):
        theta, d = offset[i], table["d"][i]
        if table["joint_types"][i] == "R":
            theta = theta + qi
        else:
            d = d + qi
        if not modified:
            T = T @ _A_std(theta, d, table["a"][i], table["alpha"][i]) @ _Ry(beta[i])
        else:  # Rx(alpha) Tx(a) = the first factor of _A_mdh at theta = d = 0
            T = T @ _A_mdh(0.0, 0.0, table["a"][i], table["alpha"][i]) @ _Ry(beta[i]) @ _A_mdh(theta, d, 0.0, 0.0)
    return T
