"""Figures of an identification report, as matplotlib ``Figure`` objects (no pyplot, no display).

Each function returns a new :class:`matplotlib.figure.Figure` for :meth:`Report.add_figure`.
Series come as ``label -> array`` mappings (``{"before": ..., "after": ...}`` or one entry per
coefficient); a single array or :class:`ResidualDiagnosis` is accepted where one series makes
sense. Angles and angular rates named in ``degrees`` are given in radians (rad/s) and drawn in
degrees (deg/s).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
from matplotlib import rcParams
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.textpath import text_to_path

from drake_uav.identification.statistics.residuals import ResidualDiagnosis

__all__ = [
    "autocorrelation_plot",
    "normal_probability_plot",
    "reconstruction_plot",
    "residual_time_series",
    "spectral_density_plot",
]

#: Time series longer than this are drawn as their min/max envelope (:func:`_envelope`).
DISPLAY_POINTS = 2000

#: Display units of the channels drawn in degrees: angles in deg, body rates in deg/s.
DEGREE_UNITS = {"alpha": "deg", "beta": "deg", "roll": "deg", "pitch": "deg", "yaw": "deg",
                "p": "deg/s", "q": "deg/s", "r": "deg/s"}

_BEFORE = dict(color="0.55", lw=0.8)
_AFTER = dict(color="C0", lw=0.8)


#: Space [in] around the panels that holds no tick label: outer border, gap between stacked
#: panels whose x tick labels are hidden, and the room of a panel title.
_BORDER, _GAP, _TITLE = 0.08, 0.14, 0.3

#: Titles sit on the top of their axes (no tick labels there). Given, the height spares the
#: search for the top axis' tick labels that an automatic title position makes at each draw.
_TITLE_Y = 1.0


def _text_size(text: str, size) -> tuple[float, float]:
    """Width and height [in] of ``text`` at font ``size``, from the font metrics alone."""
    width, height, _ = text_to_path.get_text_width_height_descent(
        text, FontProperties(size=size), ismath="$" in text)
    return width / 72.0, height / 72.0


def _y_label_room(ax: Axes) -> float:
    """Width [in] left of ``ax`` taken by its y tick labels, ticks and y label."""
    axis = ax.yaxis
    labels = [t for t in axis.get_major_formatter().format_ticks(axis.get_majorticklocs()) if t]
    ticks = max((_text_size(t, rcParams["ytick.labelsize"])[0] for t in labels), default=0.0)
    pads = (rcParams["ytick.major.size"] + rcParams["ytick.major.pad"]
            + rcParams["axes.labelpad"]) / 72.0
    label = _text_size("Ay", rcParams["axes.labelsize"])[1] * 1.3 if ax.get_ylabel() else 0.0
    return ticks + pads + label


def _x_label_room(ax: Axes) -> float:
    """Height [in] below ``ax`` taken by its x tick labels, ticks and x label."""
    tick = _text_size("0", rcParams["xtick.labelsize"])[1] * 1.3
    pads = (rcParams["xtick.major.size"] + rcParams["xtick.major.pad"]
            + rcParams["axes.labelpad"]) / 72.0
    return tick + pads + _text_size("Ay", rcParams["axes.labelsize"])[1] * 1.3


def _fixed_layout(fig: Figure, axes: np.ndarray, *, title: bool = False) -> None:
    """Places the (rows, cols) ``axes`` with margins measured from their tick labels.

    A layout engine finds the same margins by drawing every text of the figure, twice;
    the tick labels' font metrics give them without drawing. Stacked panels share their
    x axis (labels on the bottom row only); side-by-side panels each have y labels.
    """
    rows, cols = axes.shape
    width, height = fig.get_size_inches()
    left = max(_y_label_room(ax) for ax in axes.ravel()) + _BORDER
    offset = any(ax.yaxis.get_major_formatter().get_offset() for ax in axes.ravel())
    top = _BORDER + (_TITLE if title else 0.08) + (0.15 if offset else 0.0)
    bottom = _x_label_room(axes[-1, 0]) + _BORDER
    right = 0.2
    panel_w = (width - left - right - (cols - 1) * (left + 0.1)) / cols
    panel_h = (height - top - bottom - (rows - 1) * (_GAP + (_TITLE if title else 0.0))) / rows
    fig.subplots_adjust(left=left / width, right=1.0 - right / width, bottom=bottom / height,
                        top=1.0 - top / height, wspace=(left + 0.1) / panel_w,
                        hspace=(_GAP + (_TITLE if title else 0.0)) / panel_h)


def _diagnoses(diagnoses) -> dict[str, ResidualDiagnosis]:
    if isinstance(diagnoses, ResidualDiagnosis):
        return {"residual": diagnoses}
    out = dict(diagnoses)
    if not out:
        raise ValueError("no diagnosis to plot")
    for label, d in out.items():
        if not isinstance(d, ResidualDiagnosis):
            raise TypeError(f"{label!r}: expected a ResidualDiagnosis, got {type(d).__name__}")
    return out


def _one_panel(diagnoses) -> tuple[Figure, Axes, list[tuple[str, str, ResidualDiagnosis]]]:
    """A one-panel figure for several diagnoses: (figure, axes, [(colour, label, diagnosis)])."""
    items = _diagnoses(diagnoses).items()
    fig = Figure(figsize=(8.0, 3.6))
    return fig, fig.subplots(), [(f"C{i}", label, d) for i, (label, d) in enumerate(items)]


def _envelope(t: np.ndarray, y: np.ndarray, max_points: int = DISPLAY_POINTS):
    """(t, y) reduced to the min and max of consecutive blocks, in time order.

    A long noisy trace drawn at report resolution looks the same (every block keeps its
    extremes) and renders far faster; series of at most ``max_points`` are returned unchanged.
    """
    n = y.size
    if n <= max_points:
        return t, y
    k = int(np.ceil(2 * n / max_points))
    m = n // k
    blocks = y[: m * k].reshape(m, k)
    lo, hi = blocks.argmin(axis=1), blocks.argmax(axis=1)
    idx = np.sort(np.stack([lo, hi], axis=1), axis=1) + (np.arange(m) * k)[:, None]
    idx = np.concatenate([idx.ravel(), np.arange(m * k, n)])
    return t[idx], y[idx]


def _series(name: str, values, n: int) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    if v.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},) to match time, got {v.shape}")
    return v


def residual_time_series(
    time: np.ndarray,
    before: Mapping[str, np.ndarray] | np.ndarray,
    after: Mapping[str, np.ndarray] | np.ndarray | None = None,
    *,
    unit: str = "-",
    floor: Mapping[str, float] | None = None,
) -> Figure:
    """Residual against time, one panel per coefficient, before (grey) and after (blue).

    Args:
        time: (N,) sample times [s].
        before: coefficient name -> (N,) residual of the baseline model, or one array.
        after: same names -> residual of the updated model (optional).
        unit: residual unit for the y labels ("-" for non-dimensional coefficients).
        floor: name -> noise floor (RMS, same unit), drawn as dashed lines at +-floor.
    """
    t = np.asarray(time, dtype=float)
    before = {"residual": before} if isinstance(before, np.ndarray) else dict(before)
    if after is not None:
        after = {"residual": after} if isinstance(after, np.ndarray) else dict(after)
        missing = set(after) - set(before)
        if missing:
            raise ValueError(f"after has series missing from before: {sorted(missing)}")
    if not before:
        raise ValueError("no residual to plot")
    fig = Figure(figsize=(8.0, 1.2 + 1.9 * len(before)))
    grid = fig.subplots(len(before), 1, sharex=True, squeeze=False)
    axes = grid[:, 0]
    for ax, (name, values) in zip(axes, before.items(), strict=True):
        v = _series(f"before[{name!r}]", values, t.size)
        ax.plot(*_envelope(t, v), label=f"before (rms {np.sqrt(np.mean(v**2)):.3g})", **_BEFORE)
        if after is not None and name in after:
            a = _series(f"after[{name!r}]", after[name], t.size)
            ax.plot(*_envelope(t, a), label=f"after (rms {np.sqrt(np.mean(a**2)):.3g})", **_AFTER)
        ax.axhline(0.0, color="k", lw=0.5)
        if floor is not None and name in floor:
            for sign, label in ((1.0, f"noise floor {floor[name]:.3g}"), (-1.0, None)):
                ax.axhline(sign * floor[name], color="C3", ls="--", lw=0.8, label=label)
        ax.set_ylabel(f"{name} [{unit}]")
        ax.legend(loc="upper right", fontsize="small")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    _fixed_layout(fig, grid)
    return fig


def autocorrelation_plot(
    diagnoses: ResidualDiagnosis | Mapping[str, ResidualDiagnosis],
) -> Figure:
    """Residual autocorrelation against lag [s] with each diagnosis' +-bound (dashed)."""
    fig, ax, series = _one_panel(diagnoses)
    for color, label, d in series:
        verdict = "white" if d.is_white else "not white"
        ax.plot(d.acf_lag_times, d.acf, "o-", ms=2.5, lw=0.8, color=color,
                label=f"{label} (Ljung-Box p = {d.ljung_box_pvalue:.2g}, {verdict})")
        for sign in (1.0, -1.0):
            ax.axhline(sign * d.acf_bound, color=color, ls="--", lw=0.8)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("lag [s]")
    ax.set_ylabel("autocorrelation [-]")
    level = 100 * (1 - series[0][2].alpha)
    ax.set_title(f"autocorrelation, dashed: {level:.0f} % bounds", y=_TITLE_Y)
    ax.legend(fontsize="small")
    ax.grid(alpha=0.3)
    _fixed_layout(fig, np.array([[ax]]), title=True)
    return fig


def normal_probability_plot(
    diagnoses: ResidualDiagnosis | Mapping[str, ResidualDiagnosis],
    *,
    unit: str = "-",
    max_points: int = 2000,
) -> Figure:
    """Normal probability plot (Vaiopoulos 2017 4.16-4.17), one panel per diagnosis.

    Ordered residuals against ``Phi^-1((i - 1/2)/N)`` with the line ``mean + std * q`` of the
    Gaussian of the same mean and std; at most ``max_points`` points, evenly spread in rank
    (the extremes always kept).
    """
    diagnoses = _diagnoses(diagnoses)
    if max_points < 2:
        raise ValueError(f"max_points must be >= 2, got {max_points}")
    fig = Figure(figsize=(4.0 * len(diagnoses) + 0.5, 4.0))
    grid = fig.subplots(1, len(diagnoses), squeeze=False)
    axes = grid[0]
    for i, (ax, (label, d)) in enumerate(zip(axes, diagnoses.items(), strict=True)):
        idx = np.unique(np.linspace(0, d.n - 1, min(max_points, d.n)).round().astype(int))
        q = d.normal_quantiles[idx]
        ax.plot(q, d.ordered_residuals[idx], ".", ms=2.5, color=f"C{i}", label="residual")
        ends = np.array([q[0], q[-1]])
        ax.plot(ends, d.mean + d.std * ends, "k-", lw=0.8, label="Gaussian, same mean/std")
        verdict = "normal" if d.is_normal else "not normal"
        ax.set_title(f"{label}: r = {d.probability_plot_r:.4f} ({verdict})", fontsize="medium",
                     y=_TITLE_Y)
        ax.set_xlabel("standard normal quantile [-]")
        ax.set_ylabel(f"ordered residual [{unit}]")
        ax.legend(fontsize="small", loc="upper left")
        ax.grid(alpha=0.3)
    _fixed_layout(fig, grid, title=True)
    return fig


def spectral_density_plot(
    diagnoses: ResidualDiagnosis | Mapping[str, ResidualDiagnosis],
    *,
    unit: str = "-",
    nyquist_hz: float | None = None,
) -> Figure:
    """Welch PSD of the residual(s) [unit^2/Hz], log scale, significant peaks marked.

    ``nyquist_hz``: the lowest native Nyquist frequency [Hz] of the channels the residual
    is built from (:meth:`~drake_uav.identification.assessment.logged_rates.LoggedRates.
    nyquist`); nothing above it is drawn, since a log resampled onto a faster grid holds
    only its interpolation there."""
    fig, ax, series = _one_panel(diagnoses)
    top = np.inf if nyquist_hz is None else nyquist_hz
    for color, label, d in series:
        shown = d.psd_frequencies <= top
        f, p = d.psd_frequencies[1:][shown[1:]], d.psd[1:][shown[1:]]
        ax.semilogy(f, p, lw=0.8, color=color, label=label)
        ax.semilogy(d.psd_frequencies[shown], d.psd_background[shown], ":", lw=0.8,
                    color=color)
        for pk in (pk for pk in d.spectral_peaks if pk.frequency <= top):
            ax.plot(pk.frequency, pk.psd, "v", color=color, ms=6)
            ax.annotate(f"{pk.frequency:.3g} Hz", (pk.frequency, pk.psd), fontsize="x-small",
                        xytext=(3, 4), textcoords="offset points", color=color)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("PSD [1/Hz]" if unit in ("-", "1", "") else f"PSD [{unit}^2/Hz]")
    ax.set_title("residual spectral density (dotted: median background, v: peaks)", y=_TITLE_Y)
    ax.legend(fontsize="small")
    ax.grid(alpha=0.3, which="both")
    _fixed_layout(fig, np.array([[ax]]), title=True)
    return fig


def reconstruction_plot(
    time: np.ndarray,
    measured: Mapping[str, np.ndarray],
    before: Mapping[str, np.ndarray],
    after: Mapping[str, np.ndarray] | None = None,
    *,
    units: Mapping[str, str] | None = None,
    degrees: Iterable[str] = ("alpha", "beta"),
) -> Figure:
    """Output-error reconstruction: measured vs simulated channels (e.g. Va, alpha, beta).

    One panel per channel of ``measured``: measured (black), reconstructed with the baseline
    model (grey dashed) and with the updated model (blue), mean absolute errors in the legend.

    Args:
        time: (N,) [s].
        measured, before, after: channel -> (N,) values in SI units (rad, rad/s for angles
            and rates).
        units: channel -> display unit. Default: "m/s", and for channels in ``degrees``
            :data:`DEGREE_UNITS` ("deg" for angles, "deg/s" for the rates p, q, r; "deg" for
            a name it does not list).
        degrees: channels given in radians (or rad/s) and shown in degrees (or deg/s).
    """
    t = np.asarray(time, dtype=float)
    if not measured:
        raise ValueError("no measured channel to plot")
    degrees = set(degrees)
    units = dict(units or {})
    for label, series in (("before", before), ("after", after or {})):
        missing = set(series) - set(measured)
        if missing:
            raise ValueError(f"{label} has channels not in measured: {sorted(missing)}")
    fig = Figure(figsize=(8.0, 1.2 + 2.0 * len(measured)))
    grid = fig.subplots(len(measured), 1, sharex=True, squeeze=False)
    axes = grid[:, 0]
    for ax, (name, values) in zip(axes, measured.items(), strict=True):
        scale = np.degrees(1.0) if name in degrees else 1.0
        unit = units.get(name, DEGREE_UNITS.get(name, "deg") if name in degrees else "m/s")
        y = _series(f"measured[{name!r}]", values, t.size) * scale
        ax.plot(*_envelope(t, y), color="k", lw=0.9, label="measured")
        for label, series, style in (("before", before, dict(color="0.5", ls="--", lw=0.9)),
                                     ("after", after or {}, dict(color="C0", lw=0.9))):
            if name in series:
                r = _series(f"{label}[{name!r}]", series[name], t.size) * scale
                mae = float(np.mean(np.abs(r - y)))
                ax.plot(*_envelope(t, r), label=f"{label} (MAE {mae:.3g} {unit})", **style)
        ax.set_ylabel(f"{name} [{unit}]")
        ax.legend(loc="upper right", fontsize="small")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    _fixed_layout(fig, grid)
    return fig
