"""Independent reference shared by the tracking tests: the Kalman-filter covariance recursion.

For a linear-Gaussian motion model and a measurement of the position with information
J_k (R_k = J_k^-1), the posterior CRLB equals the covariance of the Kalman filter; this
computes it in covariance form (Joseph update), independently of the library's information
form.
"""

from __future__ import annotations

import numpy as np


def kf_position_mse(
    fims: np.ndarray, f: np.ndarray, q: np.ndarray, p0: np.ndarray, measure_every: int = 1
) -> np.ndarray:
    """tr(P_pos) of a Kalman filter with H = [I 0] and R_k = J_k^-1, covariance form.

    Update at step 0 (no prediction before it), then predict-update; the update uses the
    gain K = P H^T (H P H^T + R)^-1 and the Joseph form, so nothing here is information form.
    """
    n = f.shape[0]
    h = np.hstack([np.eye(2), np.zeros((2, n - 2))])
    p = p0.copy()
    out = []
    for k, jz in enumerate(fims):
        if k > 0:
            p = f @ p @ f.T + q
        if k % measure_every == 0:
            r = np.linalg.inv(jz)
            gain = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
            a = np.eye(n) - gain @ h
            p = a @ p @ a.T + gain @ r @ gain.T
        out.append(np.trace(p[:2, :2]))
    return np.array(out)
