"""Figures, log and summary of a motor-failure run (Argyropoulos 2020, ch. 6 style).

Matplotlib ``Figure`` objects (no pyplot): the 3-D path with the unsafe disc, the
states, the motor thrusts with the failed motors in red after the fault, each with
the fault time and the switch time marked and the category in the title.
:func:`fault_log` turns a run into a :class:`~drake_uav.io.flight_log.FlightLog` with
the channel and metadata names ``drake-uav replay`` reads (``motor_health_<i>``,
``failed_motors``, ``failure_time``, ``unsafe_disc``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from drake_uav.diagrams.faults import FaultRun
from drake_uav.io.flight_log import FlightLog
from drake_uav.optimization.fault_response import Category, Phase

__all__ = ["path_figure", "state_figure", "thrust_figure", "fault_log", "write_fault_outputs",
           "summary_row", "summary_table", "SUMMARY_COLUMNS"]


def _title(run: FaultRun, what: str) -> str:
    cat = "no failure" if run.category == Category.NONE else f"category {run.category.name}"
    return f"{what}: motors {list(run.failed_motors)} failed, {cat}"


def _mark_times(ax, run: FaultRun) -> None:
    if np.isfinite(run.fault_time):
        ax.axvline(run.fault_time, color="r", lw=1.0, label="fault")
    if np.isfinite(run.switch_time) and run.switch_time != run.fault_time:
        ax.axvline(run.switch_time, color="m", ls="--", lw=1.0, label="switch")


def path_figure(run: FaultRun) -> Figure:
    """Reference (black) and flown path (red) in east/north/up [m], the unsafe disc on
    the ground, the fault point, the predicted free-fall point and the touchdown."""
    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    ref, x = run.reference, run.state
    ax.plot(ref[:, 1], ref[:, 0], -ref[:, 2], "k", lw=0.8, label="reference")
    ax.plot(x[:, 1], x[:, 0], -x[:, 2], "r", label="flown")
    if run.unsafe_disc is not None:
        a = np.linspace(0, 2 * np.pi, 100)
        (n, e), r = run.unsafe_disc.center, run.unsafe_disc.radius
        ax.plot(e + r * np.sin(a), n + r * np.cos(a), 0 * a, "orange", label="unsafe disc")
    if np.isfinite(run.fault_time):
        xf = run.state_at(run.fault_time)
        ax.scatter([xf[1]], [xf[0]], [-xf[2]], color="r", marker="x", label="fault")
        ff = run.free_fall
        ax.scatter([ff.point[1]], [ff.point[0]], [0], color="gray", marker="v",
                   label="free-fall impact")
    if run.touchdown is not None:
        p = run.touchdown.position
        ax.scatter([p[1]], [p[0]], [0], color="b", marker="o", label="touchdown")
    if run.category == Category.III:
        ax.scatter([run.safe_point[1]], [run.safe_point[0]], [0], color="g", marker="s",
                   label="safe point")
    ax.set(xlabel="east [m]", ylabel="north [m]", zlabel="up [m]",
           title=_title(run, "path"))
    ax.legend(fontsize=7)
    return fig


def state_figure(run: FaultRun) -> Figure:
    """Position, velocity (NED), tilt and body rates against time."""
    fig = Figure(figsize=(9, 9))
    axes = fig.subplots(4, 1, sharex=True)
    t, x = run.time, run.state
    labels = ("north", "east", "down")
    for k in range(3):
        axes[0].plot(t, x[:, k], label=labels[k])
        axes[0].plot(t, run.reference[:, k], "k:", lw=0.7)
        axes[1].plot(t, x[:, 7 + k], label=labels[k])
    tilt = np.degrees(np.arccos(np.clip(1 - 2 * (x[:, 4]**2 + x[:, 5]**2), -1, 1)))
    axes[2].plot(t, tilt, label="tilt")
    for k, name in enumerate(("p", "q", "r")):
        axes[3].plot(t, x[:, 10 + k], label=name)
    for ax, ylabel in zip(axes, ("position [m]", "velocity [m/s]", "tilt [deg]",
                                 "body rates [rad/s]"), strict=True):
        _mark_times(ax, run)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7, loc="upper left")
    axes[0].set_title(_title(run, "states") + " (reference dotted)")
    axes[-1].set_xlabel("t [s]")
    return fig


def thrust_figure(run: FaultRun) -> Figure:
    """Commanded thrusts [N] per motor; failed motors drawn red after the fault; the
    controller's phase below."""
    fig = Figure(figsize=(9, 6))
    ax, ax_phase = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))
    failed = set(run.failed_motors)
    colors = ["C0", "C1", "C2", "C4", "C5", "C6", "C7", "C8", "C9"]  # no red: failed is red
    t = run.control_time
    after = t >= run.fault_time if np.isfinite(run.fault_time) else np.zeros(len(t), bool)
    for i in range(run.thrusts.shape[1]):
        color = colors[i % len(colors)]
        if i in failed:
            ax.step(t[~after], run.thrusts[~after, i], where="post", color=color, lw=0.9)
            ax.step(t[after], run.thrusts[after, i], where="post", color="r", lw=1.8,
                    label=f"motor {i} (failed)")
        else:
            ax.step(t, run.thrusts[:, i], where="post", color=color, lw=0.9,
                    label=f"motor {i}")
    for bound in (0.0, run.f_max):
        ax.axhline(bound, color="k", ls="--", lw=0.8)
    _mark_times(ax, run)
    ax.set(ylabel="thrust command [N]", title=_title(run, "motor thrusts"))
    ax.legend(fontsize=7, ncol=4)
    ax_phase.step(run.control_time, run.phase, where="post")
    ax_phase.set_yticks([int(p) for p in Phase], [p.name.lower() for p in Phase], fontsize=7)
    _mark_times(ax_phase, run)
    ax_phase.set(xlabel="t [s]", ylabel="phase")
    return fig


def fault_log(run: FaultRun, name: str) -> FlightLog:
    """The run as a flight log: truth state, reference, motor health and thrust commands
    on the state's time grid, and the failure in the metadata, with the names
    ``drake-uav replay`` reads."""
    t, x = run.time, run.state
    truth = {n: x[:, k] for k, n in enumerate(("pn", "pe", "pd", "qw", "qx", "qy", "qz",
                                               "vn", "ve", "vd", "p", "q", "r"))}
    units = dict.fromkeys(("pn", "pe", "pd"), "m") | dict.fromkeys(("qw", "qx", "qy", "qz"),
                                                                   "1")
    units |= dict.fromkeys(("vn", "ve", "vd"), "m/s") | dict.fromkeys(("p", "q", "r"),
                                                                      "rad/s")
    measured = {f"ref_{n}": run.reference[:, k] for k, n in enumerate(("pn", "pe", "pd"))}
    units |= dict.fromkeys(measured, "m")
    index = np.clip(np.searchsorted(run.control_time, t, side="right") - 1, 0,
                    len(run.control_time) - 1)
    for i in range(run.health.shape[1]):
        measured[f"motor_health_{i}"] = run.health[:, i]
        measured[f"thrust_{i}"] = run.thrusts[index, i]
        units[f"motor_health_{i}"], units[f"thrust_{i}"] = "1", "N"
    metadata = {"vehicle": "multirotor", "num_motors": int(run.health.shape[1]),
                "scenario": name, "failed_motors": list(run.failed_motors),
                "category": run.category.name}
    if np.isfinite(run.fault_time):
        metadata["failure_time"] = float(run.fault_time)
        metadata["switch_time"] = float(run.switch_time)
    if run.unsafe_disc is not None:
        metadata["unsafe_disc"] = {"center": [float(c) for c in run.unsafe_disc.center],
                                   "radius": float(run.unsafe_disc.radius)}
    if run.touchdown is not None:
        metadata["touchdown"] = {"time": run.touchdown.time,
                                 "position": run.touchdown.position.tolist(),
                                 "velocity": run.touchdown.velocity.tolist()}
    return FlightLog(t, measured, truth, units, metadata)


SUMMARY_COLUMNS = ("scenario", "failed", "fault [s]", "category", "switch [s]",
                   "touchdown [s]", "impact v_d [m/s]", "free fall v_d [m/s]",
                   "landing point (n, e) [m]", "RMSE after fault [m]", "real-time factor")


def summary_row(name: str, run: FaultRun) -> tuple[str, ...]:
    """One row of :data:`SUMMARY_COLUMNS` for ``run``."""
    ff = run.free_fall
    td = run.touchdown
    return (name, ",".join(map(str, run.failed_motors)) or "-", f"{run.fault_time:.3g}",
            run.category.name, f"{run.switch_time:.3g}",
            f"{td.time:.2f}" if td else "-", f"{td.vertical_speed:.2f}" if td else "-",
            f"{ff.vertical_speed:.2f}" if ff else "-",
            f"({td.position[0]:.1f}, {td.position[1]:.1f})" if td else "-",
            f"{run.position_rmse(run.fault_time):.3f}" if not td and ff else "-",
            f"{run.real_time_factor:.1f}")


def summary_table(rows) -> str:
    """Markdown table of :func:`summary_row` rows."""
    lines = ["| " + " | ".join(SUMMARY_COLUMNS) + " |",
             "|" + "---|" * len(SUMMARY_COLUMNS)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def write_fault_outputs(run: FaultRun, name: str, out: str | Path) -> list[Path]:
    """``<name>_path_3d.png``, ``<name>_states.png``, ``<name>_thrusts.png`` and the log
    ``<name>.csv`` in the folder ``out`` (which must exist); returns their paths."""
    out = Path(out)
    files = []
    for suffix, make in (("path_3d", path_figure), ("states", state_figure),
                         ("thrusts", thrust_figure)):
        fig = make(run)
        fig.tight_layout()
        path = out / f"{name}_{suffix}.png"
        fig.savefig(path, dpi=110)
        files.append(path)
    files.append(fault_log(run, name).save(out / f"{name}.csv"))
    return files
