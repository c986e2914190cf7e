"""Dryden turbulence plus steady wind as Drake systems, over :mod:`drake_uav.model.dryden`.

:class:`DrydenFilter` is the LeafSystem (one compiled update per period, noise
as an input); :class:`DrydenWind` is the diagram a flight uses: the filter, its
own Drake ``RandomSource`` (seeded through the root context) and the hold.
Output ``wind_ned`` [m/s] goes to the plant's ``wind_ned`` input, ``wind_rate_ned``
[m/s^2] to its ``wind_rate_ned`` (the gusts' part of alpha-dot).

Hold: real wind is continuous. With ``hold="first_order"`` (default) the wind
reaching the plant is the piecewise-linear interpolation of the filter samples,
one update period late (a Drake ``Integrator`` of the held slope between two
samples). No step of the wind then coincides with a sensor sample, and a
fixed-step integrator at the sensor period needs no extra step boundary.
``hold="zero_order"`` holds each sample for a period (steps at the updates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, Integrator, RandomSource

from drake_uav.model.dryden import (
    WIND_HOLDS,
    check_turbulence_level,
    compiled_filter_step,
    scale_values,
)

__all__ = ["DrydenParams", "DrydenFilter", "DrydenWind"]


@dataclass(frozen=True)
class DrydenParams:
    """Parameters of :class:`DrydenWind`.

    Attributes:
        level: "light", "moderate" or "severe".
        model: "mil-f-8785c" (altitude-dependent) or "seed" (the rows of Vaiopoulos 2017,
            Figure 7).
        steady_wind_ned: steady wind (N, E, D) [m/s].
        airspeed: fixed airspeed [m/s] for the filters; None: from ``plant_state``.
        altitude: fixed altitude [m] for the scales; None: -pD from ``plant_state``.
        update_period: filter and output sample period [s].
        update_offset: time of the first update [s], 0 <= offset < update_period.
            With ``hold="zero_order"`` a flight diagram whose sensors sample at
            the period's start sets half a period, so that the wind steps fall
            between sensor samples (a step exactly at a sample would reach the
            sampled air data and the sampled forces half a step apart).
        hold: "first_order" (continuous, piecewise-linear wind, one period late)
            or "zero_order" (each sample held for a period).
        min_airspeed: floor on the filter airspeed [m/s] (keeps V/L > 0).
    """

    level: str = "light"
    model: str = "mil-f-8785c"
    steady_wind_ned: tuple[float, float, float] = (0.0, 0.0, 0.0)
    airspeed: float | None = None
    altitude: float | None = None
    update_period: float = 0.01
    update_offset: float = 0.0
    hold: str = "first_order"
    min_airspeed: float = 1.0

    def validate(self) -> DrydenParams:
        """Raises ValueError naming the first invalid field; returns self."""
        check_turbulence_level(self.level, self.model)
        wind = np.asarray(self.steady_wind_ned, float)
        if wind.shape != (3,) or not np.all(np.isfinite(wind)):
            raise ValueError(f"steady_wind_ned: need 3 finite values, got {self.steady_wind_ned}")
        if self.airspeed is not None and not (self.airspeed > 0 and math.isfinite(self.airspeed)):
            raise ValueError(f"airspeed: must be positive and finite, got {self.airspeed}")
        if self.altitude is not None and not math.isfinite(self.altitude):
            raise ValueError(f"altitude: must be finite, got {self.altitude}")
        if not (self.update_period > 0 and math.isfinite(self.update_period)):
            raise ValueError(f"update_period: must be positive, got {self.update_period}")
        if not 0.0 <= self.update_offset < self.update_period:
            raise ValueError(f"update_offset: must be in [0, update_period), got "
                             f"{self.update_offset}")
        if self.hold not in WIND_HOLDS:
            raise ValueError(f"hold: unknown wind hold {self.hold!r}; use one of {WIND_HOLDS}")
        if not self.min_airspeed > 0:
            raise ValueError(f"min_airspeed: must be positive, got {self.min_airspeed}")
        return self

    @property
    def needs_plant_state(self) -> bool:
        """True when airspeed or altitude come from the ``plant_state`` input."""
        return self.airspeed is None or self.altitude is None


class DrydenFilter(LeafSystem):
    """Dryden shaping filters driven by an external unit Gaussian noise input.

    Discrete system sampled every ``params.update_period``; outputs are held
    between samples and depend on the state only (no direct feedthrough). The
    update (airspeed, break frequencies, exact transition, gust, rotation to NED)
    is one compiled call of the scalar-generic
    :func:`drake_uav.model.dryden._filter_step`; the length scales and
    intensities of the altitude are computed before it.

    | port (in)     | size | units                                               |
    |---------------|------|-----------------------------------------------------|
    | noise         | 6    | N(0, 1) samples, one fresh vector per period        |
    | plant_state   | 13   | plant state [pN pE pD, qw qx qy qz, u v w, p q r]   |

    | port (out)    | size | units                                               |
    |---------------|------|-----------------------------------------------------|
    | wind_ned      | 3    | steady + gust wind, NED [m/s] (the latest sample)   |
    | gust_body     | 3    | gust (u_g, v_g, w_g), body FRD [m/s]                |
    | wind_slope    | 3    | (latest - previous wind sample) / period [m/s^2]    |

    ``plant_state`` may stay unconnected when ``airspeed`` and ``altitude`` are
    fixed; the gust is then rotated with the identity attitude (NED = body).
    The airspeed taken from ``plant_state`` is relative to the steady wind
    (|v_body - R^T W_steady|), so the gust does not feed back into its own filter.
    """

    def __init__(self, params: DrydenParams = DrydenParams()):
        super().__init__()
        self._params = params.validate()
        self._steady = np.asarray(params.steady_wind_ned, float)
        self._steady_list = self._steady.tolist()
        self._has_steady = bool(np.any(self._steady))
        self._noise = self.DeclareVectorInputPort("noise", 6)
        self._plant_state = self.DeclareVectorInputPort("plant_state", 13)
        # Discrete state: the filter's own group (cascade states (z1, z2) per axis, a
        # started flag, the latest wind sample NED and gust sample body) and the slope,
        # which the Integrator of the first-order hold reads at every step (a state
        # output port: no Python call). The two samples are output from the first group.
        self._filter = self.DeclareDiscreteState([0.0] * 7 + self._steady_list + [0.0] * 3)
        slope = self.DeclareDiscreteState(3)
        self.DeclarePeriodicDiscreteUpdateEvent(params.update_period, params.update_offset,
                                                self._update)
        samples = {self.discrete_state_ticket(self._filter)}
        for name, part in (("wind_ned", slice(7, 10)), ("gust_body", slice(10, 13))):
            self.DeclareVectorOutputPort(
                name, 3, lambda context, output, part=part: output.SetFromVector(
                    context.get_discrete_state(self._filter).get_value()[part]),
                prerequisites_of_calc=samples)
        self.DeclareStateOutputPort("wind_slope", slope)
        self._step = compiled_filter_step(params.update_period, tuple(self._steady_list),
                                           params.min_airspeed).program
        fixed = params.airspeed if params.airspeed is not None else 0.0
        self._fixed_airspeed = [fixed]
        # Plant state with the identity attitude, for a fixed airspeed and altitude.
        self._level_state = [0.0, 0.0, 0.0, 1.0] + [0.0] * 9

    @property
    def params(self) -> DrydenParams:
        """The validated parameters."""
        return self._params

    def _update(self, context, discrete_state) -> None:
        p = self._params
        if self._plant_state.HasValue(context):
            state = self._plant_state.Eval(context).tolist()
        elif p.needs_plant_state:
            raise RuntimeError(
                "DrydenFilter: input 'plant_state' is not connected but DrydenParams "
                "leaves airspeed or altitude to it"
            )
        else:
            state = self._level_state
        altitude = -state[2] if p.altitude is None else p.altitude
        if not math.isfinite(altitude + sum(state)):
            raise RuntimeError(
                f"DrydenFilter: input 'plant_state' is not finite at t = "
                f"{context.get_time():.3f} s ({state}); the aircraft state is no longer "
                "finite (the simulation diverged)")
        out = self._step(context.get_discrete_state(self._filter).get_value().tolist(),
                         self._noise.Eval(context).tolist(), state,
                         scale_values(p.level, altitude, p.model), self._fixed_airspeed)
        discrete_state.set_value(0, out[:13])
        discrete_state.set_value(1, out[13:])


class DrydenWind(Diagram):
    """Steady wind plus Dryden turbulence with its own Gaussian noise source.

    A small diagram: a Drake ``RandomSource`` (6 unit Gaussians per period)
    feeding a :class:`DrydenFilter`, and for ``hold="first_order"`` an
    ``Integrator`` of the filter's ``wind_slope`` that starts at the steady wind.
    Seed it through the root context with
    ``diagram.SetRandomContext(context, RandomGenerator(seed))``.

    | port (in)     | size | units                                               |
    |---------------|------|-----------------------------------------------------|
    | plant_state   | 13   | plant ``state`` output (no feedthrough: no loop)    |

    | port (out)    | size | units                                               |
    |---------------|------|-----------------------------------------------------|
    | wind_ned      | 3    | steady + gust wind, NED [m/s] -> plant ``wind_ned`` |
    | wind_rate_ned | 3    | d(wind_ned)/dt [m/s^2] -> plant ``wind_rate_ned``   |
    | gust_body     | 3    | latest gust sample (u_g, v_g, w_g), body FRD [m/s]  |

    With the first-order hold, ``wind_ned`` passes each filter sample one
    update period after it was drawn (``gust_body`` is the filter sample itself)
    and ``wind_rate_ned`` is the slope it follows; with the zero-order hold the wind
    only steps, and ``wind_rate_ned`` is zero (the steps are not a rate).
    """

    def __init__(self, params: DrydenParams = DrydenParams()):
        super().__init__()
        params.validate()
        builder = DiagramBuilder()
        noise = builder.AddNamedSystem(
            "dryden_noise",
            RandomSource(RandomDistribution.kGaussian, 6, params.update_period),
        )
        self.filter = builder.AddNamedSystem("dryden_filter", DrydenFilter(params))
        builder.Connect(noise.get_output_port(0), self.filter.GetInputPort("noise"))
        builder.ExportInput(self.filter.GetInputPort("plant_state"), "plant_state")
        wind = self.filter.GetOutputPort("wind_ned")
        if params.hold == "first_order":
            hold = builder.AddNamedSystem(
                "first_order_hold", Integrator(np.asarray(params.steady_wind_ned, float)))
            rate = self.filter.GetOutputPort("wind_slope")
            builder.Connect(rate, hold.get_input_port())
            wind = hold.get_output_port()
        else:
            rate = builder.AddNamedSystem("steps_have_no_rate", ConstantVectorSource(
                np.zeros(3))).get_output_port(0)
        builder.ExportOutput(wind, "wind_ned")
        builder.ExportOutput(rate, "wind_rate_ned")
        builder.ExportOutput(self.filter.GetOutputPort("gust_body"), "gust_body")
        builder.BuildInto(self)

    @property
    def params(self) -> DrydenParams:
        """The validated parameters."""
        return self.filter.params
