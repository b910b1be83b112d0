"""Shared test configuration and an independent reference model of the range sensing.

Hypothesis runs derandomized with no deadline (CI machines are slow and noisy); set the
environment variable ``HYPOTHESIS_PROFILE=thorough`` for a longer local search.

The ``ref`` fixture gives reference functions written from the model of the paper
(the paper profile of docs/sensing-model.md), *not* from crlbswarm's formulas: the ranges
are Gaussian with mean
``mu_m(s) = sqrt(|q_m - s|^2 + H^2)`` and variance
``var_m(s) = kappa sigma0^2 mu_m^4 / (p G_p beta0)`` built from the raw radar numbers, and
the Fisher information is obtained from that likelihood by two textbook routes:

* the Slepian-Bangs formula
  ``J_ij = sum_m [dmu_i dmu_j / var + 0.5 dvar_i dvar_j / var^2]`` with the derivatives by
  complex-step differentiation, ``f'(x) = Im f(x + i h) / h`` (exact to rounding, no
  truncation error), and
* the definition ``J = E[score score^T]``, the score being the complex-step gradient of the
  log-likelihood itself and the expectation done exactly by Gauss-Hermite quadrature
  (each UAV's score is a quadratic polynomial of its own noise).

None of crlbswarm's code is used, except that the tests compare against it.
"""

from __future__ import annotations

import os

# One BLAS thread per test process (set before NumPy loads): pytest-xdist runs one worker
# per core, and BLAS threads spinning against the other worker made small SciPy solves
# (SLSQP in the constrained design) several times slower.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import settings
from numpy.polynomial.hermite_e import hermegauss
from scipy.optimize import brentq

settings.register_profile("ci", deadline=None, derandomize=True, max_examples=100, database=None)
settings.register_profile("thorough", deadline=None, max_examples=1000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

#: Speed of light, m/s (SI definition), typed in here rather than imported.
C_LIGHT = 299_792_458.0

#: Complex-step size: small enough that the O(h^2) error is far below rounding.
CS_STEP = 1e-30

#: The paper profile of the paper profile of docs/sensing-model.md, in raw linear SI units.
PAPER_PROFILE = {
    "tx_power": 0.1,  # p, W
    "noise_power": 1e-12,  # sigma0^2, W (-90 dBm)
    "processing_gain": 1000.0,  # G_p (30 dB)
    "tx_gain": 1.0,  # G_T (0 dBi)
    "rx_gain": 1.0,  # G_r (0 dBi)
    "rcs": 1.0,  # m^2
    "carrier_frequency": 5.8e9,  # f_c, Hz
    "kappa": 1.0,
}


def radar_params(**changes: object) -> SimpleNamespace:
    """Raw radar numbers (paper profile unless changed); fields may be per-UAV arrays."""
    params = dict(PAPER_PROFILE)
    params.update(changes)
    return SimpleNamespace(**{k: np.asarray(v, dtype=float) for k, v in params.items()})


def beta0(prm: SimpleNamespace) -> np.ndarray:
    """beta0 = G_T G_r rcs lambda^2 / (4 pi)^3 with lambda = c / f_c."""
    wavelength = C_LIGHT / prm.carrier_frequency
    return prm.tx_gain * prm.rx_gain * prm.rcs * wavelength**2 / (4.0 * math.pi) ** 3


def snr_constant(prm: SimpleNamespace) -> np.ndarray:
    """A = p G_p beta0 / (kappa sigma0^2), m^4."""
    return prm.tx_power * prm.processing_gain * beta0(prm) / (prm.kappa * prm.noise_power)


def range_mean(q: np.ndarray, s: np.ndarray, altitude: float) -> np.ndarray:
    """mu_m(s) = sqrt(|q_m - s|^2 + H^2), shape (M,); analytic, so s may be complex."""
    dx = q[:, 0] - s[0]
    dy = q[:, 1] - s[1]
    return np.sqrt(dx * dx + dy * dy + altitude * altitude)


def range_var(mu: np.ndarray, prm: SimpleNamespace) -> np.ndarray:
    """var_m = kappa sigma0^2 mu_m^4 / (p G_p beta0), from the raw radar numbers."""
    return prm.kappa * prm.noise_power * mu**4 / (prm.tx_power * prm.processing_gain * beta0(prm))


def complex_step_grad(f, s: np.ndarray) -> np.ndarray:
    """Gradient of f: C^2 -> C^(...) at the real point s, shape (2, ...), by complex step."""
    s = np.asarray(s, dtype=complex)
    return np.stack([np.imag(f(s + 1j * CS_STEP * e)) / CS_STEP for e in np.eye(2)])


def fim_slepian_bangs(
    q: np.ndarray, s: np.ndarray, altitude: float, prm: SimpleNamespace
) -> np.ndarray:
    """2x2 FIM of the target by the Slepian-Bangs formula (Gaussian, mean and variance)."""
    q = np.asarray(q, dtype=float)
    s = np.asarray(s, dtype=float)
    var = range_var(range_mean(q, s, altitude), prm)
    dmu = complex_step_grad(lambda x: range_mean(q, x, altitude), s)  # (2, M)
    dvar = complex_step_grad(lambda x: range_var(range_mean(q, x, altitude), prm), s)
    return (dmu / var) @ dmu.T + 0.5 * (dvar / var**2) @ dvar.T


def log_likelihood_terms(
    dhat: np.ndarray, q: np.ndarray, s: np.ndarray, altitude: float, prm: SimpleNamespace
) -> np.ndarray:
    """ln N(dhat_m; mu_m(s), var_m(s)) for each UAV, shape of ``dhat`` (..., M)."""
    mu = range_mean(q, s, altitude)
    var = range_var(mu, prm)
    return -0.5 * np.log(2.0 * np.pi * var) - (dhat - mu) ** 2 / (2.0 * var)


def fim_expected_score(
    q: np.ndarray, s: np.ndarray, altitude: float, prm: SimpleNamespace, n_nodes: int = 5
) -> tuple[np.ndarray, np.ndarray]:
    """FIM as E[score score^T], with each UAV's expectation done by Gauss-Hermite quadrature.

    The score of ln p(dhat | s) = sum_m ln p_m(dhat_m | s) is sum_m g_m(dhat_m), each g_m a
    quadratic polynomial of UAV m's noise, so ``n_nodes >= 3`` nodes give E[g_m g_m^T]
    (degree 4) and E[g_m] exactly. With independent UAVs,
    E[g g^T] = sum_m E[g_m g_m^T] + sum_{m != n} E[g_m] E[g_n]^T.

    Returns ``(J, mean_scores)``, the latter of shape (M, 2) (zero for a valid likelihood).
    """
    q = np.asarray(q, dtype=float)
    s = np.asarray(s, dtype=float)
    nodes, weights = hermegauss(n_nodes)  # probabilists' Hermite: weight exp(-x^2 / 2)
    weights = weights / np.sqrt(2.0 * np.pi)
    mu = range_mean(q, s, altitude)
    sd = np.sqrt(range_var(mu, prm))
    dhat = mu + sd * nodes[:, None]  # (K, M): quadrature points of every UAV's range
    score = complex_step_grad(lambda x: log_likelihood_terms(dhat, q, x, altitude, prm), s)
    score = np.moveaxis(score, 0, -1)  # (K, M, 2)
    second = np.einsum("k,kmi,kmj->mij", weights, score, score)  # E[g_m g_m^T]
    first = np.einsum("k,kmi->mi", weights, score)  # E[g_m]
    total = first.sum(axis=0)
    fim = second.sum(axis=0) - first.T @ first + np.outer(total, total)
    return fim, first


def information_weight(phi: np.ndarray, altitude: np.ndarray, a: np.ndarray) -> np.ndarray:
    """w(phi) = (A sin^4 phi / H^4 + 8 sin^2 phi / H^2) cos^2 phi (docs/optimal-formation.md)."""
    s2 = np.sin(phi) ** 2
    return (a * s2**2 / altitude**4 + 8.0 * s2 / altitude**2) * np.cos(phi) ** 2


def optimal_elevation_numeric(altitude: float, a: float) -> float:
    """argmax of w over (0, pi/2): brentq on the complex-step derivative of w.

    dw/dphi changes sign exactly once (w vanishes at both ends and is unimodal); the
    complex-step derivative has no truncation error, so the root is found to ~1e-15 rad.
    """

    def dw(phi: float) -> float:
        return np.imag(information_weight(phi + 1j * CS_STEP, altitude, a)) / CS_STEP

    return brentq(dw, 1e-6, 0.5 * np.pi - 1e-6, xtol=1e-15, rtol=4 * np.finfo(float).eps)


def crlb_of_fim(fim: np.ndarray) -> float:
    """tr(J^-1) with numpy.linalg."""
    return float(np.trace(np.linalg.inv(fim)))


def d_optimality_of_fim(fim: np.ndarray) -> float:
    """det(J^-1) with numpy.linalg."""
    return float(np.linalg.det(np.linalg.inv(fim)))


def e_optimality_of_fim(fim: np.ndarray) -> float:
    """lambda_max(J^-1) with numpy.linalg."""
    return float(np.max(np.linalg.eigvalsh(np.linalg.inv(fim))))


def random_formation(
    rng: np.random.Generator, n_uavs: int, scale: float, center: np.ndarray | None = None
) -> np.ndarray:
    """n_uavs positions uniform in a disc of radius ``scale`` (around ``center``), (M, 2)."""
    rho = scale * np.sqrt(rng.random(n_uavs))
    theta = 2.0 * np.pi * rng.random(n_uavs)
    xy = np.stack([rho * np.cos(theta), rho * np.sin(theta)], axis=-1)
    return xy if center is None else xy + center


_REFERENCE = SimpleNamespace(
    C_LIGHT=C_LIGHT,
    PAPER_PROFILE=PAPER_PROFILE,
    radar_params=radar_params,
    beta0=beta0,
    snr_constant=snr_constant,
    range_mean=range_mean,
    range_var=range_var,
    complex_step_grad=complex_step_grad,
    fim_slepian_bangs=fim_slepian_bangs,
    log_likelihood_terms=log_likelihood_terms,
    fim_expected_score=fim_expected_score,
    information_weight=information_weight,
    optimal_elevation_numeric=optimal_elevation_numeric,
    crlb_of_fim=crlb_of_fim,
    d_optimality_of_fim=d_optimality_of_fim,
    e_optimality_of_fim=e_optimality_of_fim,
    random_formation=random_formation,
)


@pytest.fixture(scope="session")
def ref() -> SimpleNamespace:
    """The independent reference model above (session scope: usable under hypothesis)."""
    return _REFERENCE


def readonly(value: object) -> np.ndarray:
    """A read-only float copy of ``value``."""
    arr = np.array(value, dtype=float)
    arr.flags.writeable = False
    return arr


@pytest.fixture(scope="session")
def make_readonly():
    """Factory of read-only float arrays, to check that no function writes to its inputs."""
    return readonly


#: The tables that switch every layer beyond the paper off (safety filter, route planner,
#: optimal slot assignment): a scenario with them flies the paper's own laws.
PAPER_LAWS = {
    "safety": {"enabled": False},
    "guidance": {"planner": False},
    "formation": {"assignment": "index"},
}
