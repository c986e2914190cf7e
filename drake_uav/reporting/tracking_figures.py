"""Figures of a tracking run: 3-D path, position error, motor thrusts, NMPC solve times.

Matplotlib ``Figure`` objects (no pyplot, no display), written as PNG files by
:func:`write_tracking_plots` into a plot folder that follows the overwrite rule of
:mod:`drake_uav.reporting.output` (missing, empty or earlier plots only; swapped in complete).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from drake_uav.diagrams.tracking import TrackingRun
from drake_uav.reporting.output import output_folder

__all__ = ["path_figure", "position_error_figure", "thrust_figure", "solve_time_figure",
           "write_tracking_plots"]


def path_figure(run: TrackingRun) -> Figure:
    """Reference and flown path in east/north/up axes [m]."""
    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    ref = run.reference
    ax.plot(ref[:, 1], ref[:, 0], -ref[:, 2], "k", label="reference")
    ax.plot(run.state[:, 1], run.state[:, 0], -run.state[:, 2], "r", label="flown")
    ax.set(xlabel="east [m]", ylabel="north [m]", zlabel="up [m]", title="path")
    ax.legend()
    return fig


def position_error_figure(run: TrackingRun) -> Figure:
    """Distance to the reference position [m] on a log scale."""
    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot()
    ax.semilogy(run.time, np.maximum(run.position_error, 1e-6))
    ax.set(xlabel="t [s]", ylabel="|p - p_r| [m]", title="position error")
    return fig


def thrust_figure(run: TrackingRun) -> Figure:
    """Commanded motor thrusts [N] with the bounds [0, f_max]."""
    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot()
    ax.step(run.control_time, run.thrusts, where="post", lw=0.8)
    for bound in (0.0, run.f_max):
        ax.axhline(bound, color="k", ls="--", lw=0.8)
    ax.set(xlabel="t [s]", ylabel="thrust [N]", title="motor thrusts and bounds")
    return fig


def solve_time_figure(run: TrackingRun) -> Figure:
    """Solve time per control step [ms]; the steps of the fallback law marked red."""
    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot()
    ax.plot(run.control_time, 1e3 * run.solve_time, ".", ms=2)
    fallback = run.status != 0
    ax.plot(run.control_time[fallback], 1e3 * run.solve_time[fallback], "rx", ms=4,
            label="fallback")
    ax.set(xlabel="t [s]", ylabel="solve time [ms]", title="NMPC solve time per step")
    ax.legend()
    return fig


def write_tracking_plots(run: TrackingRun, out: str | Path) -> list[Path]:
    """The four figures as PNGs in the folder ``out``; returns their paths.

    ``out`` may be missing, empty or an earlier plot folder (it holds only files its
    manifest lists); it appears complete or not at all.

    Raises
    ------
    OutputRefusedError
        ``out`` is a file or a folder holding anything else (nothing is written).
    """
    out = Path(out)
    names = []
    with output_folder(out, "tracking plots", what="plot folder") as partial:
        for name, make in (("path_3d.png", path_figure),
                           ("position_error.png", position_error_figure),
                           ("thrusts.png", thrust_figure), ("solve_times.png",
                                                            solve_time_figure)):
            fig = make(run)
            fig.tight_layout()
            fig.savefig(partial / name, dpi=110)
            names.append(name)
    return [out / name for name in names]
