"""Figures of the paper, drawn from experiment results.

Every function takes a result object and an optional Matplotlib ``ax``, draws on it, and
returns the :class:`matplotlib.figure.Figure`. Nothing here calls ``plt.show()``, saves a
file or touches pyplot's global state: figures are built with the object-oriented API, so
they work on a machine without a display. Only the CLI saves files.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .experiments import FORMATION_LABELS, AltitudeSweep, ElevationCurve

__all__ = ["plot_crlb_vs_altitude", "plot_optimal_elevation"]

_STYLES = {
    "optimal": {"color": "C3", "lw": 2.2, "marker": "o", "ms": 4},
    "fixed_polygon": {"color": "C0", "marker": "s", "ms": 3.5},
    "arc": {"color": "C2", "marker": "^", "ms": 3.5},
    "line": {"color": "C1", "marker": "v", "ms": 3.5},
    "random_disc": {"color": "C4", "marker": "D", "ms": 3},
}


def plot_crlb_vs_altitude(
    sweep: AltitudeSweep, ax: Axes | None = None, ratio_ax: Axes | None = None
) -> Figure:
    """Fig. 2: CRLB against altitude for F* and every benchmark formation (log scale).

    With no axes given, the figure has two panels: the CRLB itself (as in the paper) and
    the CRLB divided by the bound 4/sum(w*), on which F* is the line 1 and every benchmark
    sits above it at every altitude.

    Parameters
    ----------
    sweep : AltitudeSweep
        Result of :func:`crlbswarm.crlb_vs_altitude`.
    ax : matplotlib.axes.Axes, optional
        Axes for the CRLB panel; if omitted a new two-panel figure is made.
    ratio_ax : matplotlib.axes.Axes, optional
        Axes for the ratio panel; drawn only if given or if ``ax`` is omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if ax is None:
        fig = Figure(figsize=(6.4, 7.2), layout="constrained")
        ax, ratio_ax = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    fig = ax.figure
    h = sweep.altitude
    for name, values in sweep.crlb.items():
        label = FORMATION_LABELS.get(name, name)
        if name == "fixed_polygon":
            label = f"regular polygon, r = {sweep.parameters['fixed_radius_m']:g} m"
        style = _STYLES.get(name, {})
        sem = sweep.sem.get(name)
        for axis, scale in ((ax, 1.0), (ratio_ax, sweep.bound)):
            if axis is None:
                continue
            axis.plot(h, values / scale, label=label, **style)
            if sem is not None and np.any(sem):
                axis.fill_between(
                    h,
                    (values - 2 * sem) / scale,
                    (values + 2 * sem) / scale,
                    color=style.get("color"),
                    alpha=0.2,
                    lw=0,
                )
    ax.plot(h, sweep.bound, "k--", lw=1.0, label=r"bound $4/\sum_m w_m^*$, eq. (11)")
    ax.set_yscale("log")
    ax.set_ylabel(r"CRLB tr$(\mathbf{J}_s^{-1})$ (m$^2$)")
    ax.set_title(f"CRLB vs altitude, M = {sweep.n_uavs} UAVs")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    last = ax
    if ratio_ax is not None:
        ratio_ax.axhline(1.0, color="k", ls="--", lw=1.0)
        ratio_ax.set_yscale("log")
        ratio_ax.set_ylabel("CRLB / bound")
        ratio_ax.grid(True, which="both", alpha=0.3)
        last = ratio_ax
    last.set_xlabel("flight altitude H (m)")
    return fig


def plot_optimal_elevation(curve: ElevationCurve, ax: Axes | None = None) -> Figure:
    """Optimal elevation against altitude on a log axis, with its limits 54.74 and 45 deg.

    Parameters
    ----------
    curve : ElevationCurve
        Result of :func:`crlbswarm.optimal_elevation_curve`.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure is made if omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if ax is None:
        ax = Figure(figsize=(6.4, 4.0), layout="constrained").add_subplot()
    fig = ax.figure
    ax.plot(curve.altitude, np.degrees(curve.elevation), color="C3", lw=2, label=r"$\phi^*(H)$")
    upper = np.degrees(np.arctan(np.sqrt(2.0)))
    ax.axhline(
        upper, color="0.3", ls="--", lw=1, label=rf"$\arctan\sqrt{{2}}$ = {upper:.2f}° ($H \to 0$)"
    )
    ax.axhline(45.0, color="0.3", ls=":", lw=1, label=r"45° ($H \to \infty$)")
    ax.set_xscale("log")
    ax.set_xlabel("flight altitude H (m)")
    ax.set_ylabel(r"optimal elevation $\phi^*$ (deg)")
    ax.set_ylim(44.0, 56.0)
    ax.set_title("CRLB-optimal elevation angle")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    return fig
