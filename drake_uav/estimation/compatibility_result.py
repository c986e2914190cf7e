"""The result of the data-compatibility check: named calibration effects with their
uncertainty and verdict, and the log with the significant ones removed.

An effect is *significant* when it is observable (the data determine it to better than
its tolerance), statistically significant (two-sided t test at ``significance`` with the
fit's degrees of freedom) and larger than its practical tolerance. The check itself is
:func:`drake_uav.estimation.compatibility.check_compatibility`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from drake_uav.estimation.compatibility_fits import fresh_times, t_p_value, wrap
from drake_uav.estimation.signals import HELD_FRACTION
from drake_uav.io.flight_log import FlightLog, FlightLogError

__all__ = ["CalibrationEffect", "CompatibilityResult", "SIGNIFICANCE", "read_later"]

SIGNIFICANCE = 0.01
"""Two-sided p-value below which an effect is statistically significant."""


@dataclasses.dataclass(frozen=True)
class CalibrationEffect:
    """One calibration error estimated from the sensors' redundancy."""

    name: str
    """e.g. ``airspeed_scale_factor``, ``gps_time_skew``, ``gyro_bias_q``."""
    channels: tuple[str, ...]
    """Measured channels it corrects."""
    estimate: float
    """[unit]; NaN when the data could not fit it."""
    sigma: float
    """Standard error (time-block sandwich) [unit]."""
    dof: int
    """Degrees of freedom of its t statistic."""
    unit: str
    """SI unit of ``estimate`` ("1" for a scale factor, "s" for a skew)."""
    nominal: float
    """Value of a calibrated sensor (1 for a scale factor, 0 otherwise)."""
    tolerance: float
    """Practical tolerance on ``|estimate - nominal|`` [unit]."""
    explanation: str
    observable: bool = True
    note: str = ""
    """Why it is not observable or not corrected, when it is not."""
    correctable: bool = True
    significance: float = SIGNIFICANCE
    drives: bool = False
    """A skew of channels that drive the IMU's response (the commands): it says how much
    later the response comes, so the channels are read that much earlier to remove it."""

    @property
    def error(self) -> float:
        """``estimate - nominal`` [unit]."""
        return self.estimate - self.nominal

    @property
    def p_value(self) -> float:
        """Two-sided p-value of ``error / sigma`` (t with ``dof`` degrees of freedom)."""
        return t_p_value(self.error / self.sigma if self.sigma > 0 else math.inf, self.dof)

    @property
    def significant(self) -> bool:
        """Observable, statistically significant and beyond the practical tolerance."""
        return (self.observable and self.p_value < self.significance
                and abs(self.error) > self.tolerance)

    @property
    def applied(self) -> bool:
        """True when :meth:`CompatibilityResult.corrected` removes it."""
        return self.significant and self.correctable

    def summary(self) -> dict:
        """JSON-ready fields."""
        return {"name": self.name, "channels": list(self.channels), "estimate": self.estimate,
                "sigma": self.sigma, "unit": self.unit, "nominal": self.nominal,
                "tolerance": self.tolerance, "p_value": self.p_value, "dof": self.dof,
                "observable": self.observable, "significant": self.significant,
                "applied": self.applied, "explanation": self.explanation, "note": self.note}

    def line(self) -> str:
        """One line for a report: the value in display units and the verdict."""
        factor, unit = _DISPLAY.get(self.unit, (1.0, self.unit))
        value = (f"{self.estimate * factor:+.4g} +- {self.sigma * factor:.2g} {unit}".rstrip()
                 if math.isfinite(self.estimate) else "not estimated")
        verdict = ("not observable" if not self.observable else
                   "corrected" if self.applied else "significant, not corrected"
                   if self.significant else "within tolerance")
        tolerance = f"tolerance {self.tolerance * factor:.3g} {unit}".rstrip()
        tail = f"; {self.note}" if self.note else ""
        return f"{self.name}: {value} ({tolerance}): {verdict}{tail}"


_DISPLAY = {"rad": (180.0 / math.pi, "deg"), "rad/s": (180.0 / math.pi, "deg/s"),
            "1": (1.0, "")}


@dataclasses.dataclass(frozen=True)
class CompatibilityResult:
    """What the data-compatibility check found, and the log it corrects."""

    effects: tuple[CalibrationEffect, ...]
    notes: tuple[str, ...] = ()
    """What was not checked and why, and the estimated winds."""

    def __getitem__(self, name: str) -> CalibrationEffect:
        for effect in self.effects:
            if effect.name == name:
                return effect
        raise KeyError(f"no calibration effect {name!r} (checked: "
                       f"{', '.join(e.name for e in self.effects) or 'none'})")

    @property
    def significant(self) -> tuple[CalibrationEffect, ...]:
        """The significant effects."""
        return tuple(e for e in self.effects if e.significant)

    @property
    def applied(self) -> tuple[CalibrationEffect, ...]:
        """The effects :meth:`corrected` removes."""
        return tuple(e for e in self.effects if e.applied)

    def summary(self) -> dict:
        """JSON-ready: every effect and the notes."""
        return {"effects": [e.summary() for e in self.effects], "notes": list(self.notes)}

    def lines(self) -> list[str]:
        """The report lines: one per effect, then the notes."""
        return [e.line() for e in self.effects] + list(self.notes)

    def corrected(self, log: FlightLog) -> FlightLog:
        """``log`` with the applied effects removed, as a new FlightLog.

        Biases are subtracted, scale factors divided out (the dynamic pressure by the
        square of the airspeed's), skews removed by reading the channels that much later
        (linear interpolation; held channels keep their hold) on the span where every
        shifted channel is defined. Truth channels only follow the span. The metadata
        gain ``compatibility_corrections``: the applied effects' summaries.
        """
        applied = self.applied
        if not applied:
            return log
        values = {n: np.array(log[n]) for n in log.measured_names}
        # Offsets before scale factors: a vane reads b + k alpha, so alpha = (reading - b) / k.
        for effect in sorted(applied, key=lambda e: e.nominal):
            if effect.unit != "s":
                _calibrate(values, effect)
        time, keep = _shifted(log, values, [e for e in applied if e.unit == "s"])
        measured = {n: v[keep] for n, v in values.items()}
        truth = {n: log[n][keep] for n in log.truth_names}
        metadata = {**log.metadata, "compatibility_corrections": [
            {k: e.summary()[k] for k in ("name", "channels", "estimate", "sigma", "unit")}
            for e in applied]}
        return FlightLog(time[keep], measured, truth, log.units, metadata)


def _calibrate(values: dict[str, np.ndarray], effect: CalibrationEffect) -> None:
    """Removes a bias (offset) or scale factor from its channels, in place."""
    for channel in effect.channels:
        if channel not in values:
            continue
        if effect.nominal == 1.0:
            power = 2.0 if channel == "pitot_qbar" else 1.0  # qbar = rho Va^2 / 2
            values[channel] = values[channel] / effect.estimate**power
        else:
            values[channel] = values[channel] - effect.estimate


def _shifted(log: FlightLog, values: dict[str, np.ndarray], skews) -> tuple:
    """Channels read ``skew`` later (in place) and the samples where all are defined."""
    time = log.time
    keep = np.ones(len(time), bool)
    for effect in skews:
        tau = -effect.error if effect.drives else effect.error
        keep &= (time + tau >= time[0]) & (time + tau <= time[-1])
        for channel in effect.channels:
            if channel in values:
                values[channel] = read_later(time, values[channel], tau,
                                             angle=log.unit(channel) == "rad")
    if not keep.any():
        raise FlightLogError("compatibility: the corrected skews leave no common samples")
    return time, keep


def read_later(time: np.ndarray, values: np.ndarray, tau: float,
               angle: bool = False) -> np.ndarray:
    """``values(t + tau)``: linear between samples, or held for a held channel; an
    ``angle`` [rad] is unwrapped first and wrapped back to [-pi, pi) where it wrapped."""
    if angle and np.any(np.abs(np.diff(values)) > np.pi):
        return wrap(read_later(time, np.unwrap(values), tau))
    fresh = fresh_times(time, values)
    if len(fresh) > HELD_FRACTION * len(time):
        return np.interp(time + tau, time, values)
    arrival = time[fresh] - tau
    index = np.clip(np.searchsorted(arrival, time, side="right") - 1, 0, len(fresh) - 1)
    return values[fresh][index]


