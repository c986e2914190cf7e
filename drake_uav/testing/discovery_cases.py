"""Scenario ``discovery``: does the main job name an undeclared effect, and only it?

One identification flight (:func:`drake_uav.diagrams.fly`, the aerosonde, 120 s) with
one effect the catalog model lacks put into the physics or the sensors, then the main
job (:func:`drake_uav.identification.pipeline.identify`) with the catalog model, reading
only what a real log holds. An effect's size is the share it adds to the variation of
the coefficient it acts on: ``size = std(term) / std(coefficient)`` over the flight, the
coefficient being the catalog model's along the true trajectory (the truth channels) and
the term the effect's change of the measured coefficient. The strength that gives a size
is calibrated once per turbulence level on clean flights of their own seeds
(:data:`CALIBRATION_SEEDS`), never on the campaign's; each run reports the size it
realised on its own flight.

A run's findings are :attr:`IdentificationRun.findings`: the calibration errors the
data-compatibility check corrected, then the effects the discovery loop found.
``exact``: the findings are exactly the injected effect; ``partial``: it is among them
with others; ``false_findings``: findings other than it (on a clean flight, every
finding).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_uav.campaigns.registry import register_scenario
from drake_uav.diagrams import fly
from drake_uav.identification.assessment.families import families
from drake_uav.identification.assessment.near_ties import near_ties
from drake_uav.identification.assessment.noise_floor import held_out_noise_floor
from drake_uav.identification.discovery.fitted_point import unit_vectors_towards
from drake_uav.identification.discovery.result import EvidenceRule
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog
from drake_uav.io.propeller_table import PropellerTable
from drake_uav.model.coefficients import COEFFICIENTS, AeroCondition, body_to_lift_drag
from drake_uav.model.isolation import differentiate
from drake_uav.model.propeller import coefficient_polynomial
from drake_uav.model.rotations import euler_to_rotmat, quat_to_rotmat
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.loading import load_fixed_wing
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = ["INJECTED", "SUITES", "CALIBRATION_SEEDS", "Injection", "unit_strength_ratio",
           "discovery", "measured_only", "true_coefficients", "aero_condition", "qbar_s",
           "PULL_POINT", "PullTowardsPoint", "pull_towards_point", "tether_tension",
           "found_as_family", "RPM_AIRCRAFT", "RPM_NOISE", "RPM_MODES", "propeller_table",
           "ELECTRIC_AEROSONDE", "RPM_AIRCRAFTS", "campaign_aircraft",
           "shaft_speed_logged"]

CALIBRATION_SEEDS = (1000, 1001, 1002)
"""Seeds of the clean flights the strengths are calibrated on (none of a campaign's)."""

SUITES = {"default": lambda rho: SensorSuiteParams.seed_table7(air_density=rho),
          "research": lambda rho: SensorSuiteParams.research_grade(air_density=rho)}
"""Sensor suites by name: the low-cost default (Vaiopoulos 2017, Table 7) and a
research-grade IMU and air-data boom."""


@dataclasses.dataclass(frozen=True)
class Injection:
    """An effect put into a flight, what the job should call it, and its size's yardstick."""

    expected: str
    """The finding that names it (an effect or a calibration error)."""
    coefficient: str
    """The coefficient whose variation its size is measured against."""
    term: Callable[[AeroCondition, FlightLog, FixedWingParams], np.ndarray]
    """Its change of the measured coefficient at strength 1, along a flight's truth."""
    flight: Callable[[float, FixedWingParams], dict] = lambda strength, params: {}
    """Options of :func:`fly` (``disturbance``, ``actuator_delay``, ``aircraft``)."""
    sensors: Callable[[FlightLog, float], FlightLog] | None = None
    """A change of the logged sensors (a calibration error), at a strength."""
    strength_step: float = 0.0
    """Smallest realisable step of the strength (a delay in whole sample periods)."""
    logged: Callable[[FlightLog, float, int], FlightLog] | None = None
    """An extra channel the log gains (a load cell), at a strength and a flight's seed."""
    point: tuple[float, float, float] | None = None
    """The NED point [m] a force towards a point acts towards (its finding reports where
    the data put it)."""
    over_flight: bool = False
    """``flight`` also takes the flight's duration [s] (an effect that grows over it)."""

    def fly_options(self, strength: float, params: FixedWingParams, duration: float) -> dict:
        """Options of :func:`fly` that put the effect into a flight of ``duration`` [s]."""
        if self.over_flight:
            return self.flight(strength, params, duration)
        return self.flight(strength, params)


def _increment(index: int, shape: Callable[[AeroCondition], object]):
    """Fly options: a coefficient increment ``strength * shape`` on (CL, CD, CY, Cl, Cm, Cn)."""
    def options(strength, params):
        def increment(condition):
            out = [0.0] * 6
            out[index] = strength * shape(condition)
            return tuple(out)
        return {"disturbance": increment}
    return options


def _drift(index: int):
    """Fly options: a coefficient growing linearly from 0 by ``strength`` over the flight's
    ``duration`` [s]."""
    def options(strength, params, duration):
        def increment(condition, t):
            out = [0.0] * 6
            out[index] = strength * t / duration
            return tuple(out)
        return {"disturbance": increment}
    return options


def _share_of_flight(condition, flight, params):
    """Time since the start over the flight's duration (its log's metadata) [-]."""
    return (flight.time - flight.time[0]) / flight.metadata["duration"]


def _body_force_x(strength, params):
    return {"disturbance": np.array([strength, 0.0, 0.0, 0.0, 0.0, 0.0])}


TOW_POINT_BELOW = 0.3
"""Body z [m] of the off-centre tow force's application point (below the centre of gravity)."""


def _tow_below_cg(strength, params):
    """A body-x force of ``strength`` [N] at (0, 0, TOW_POINT_BELOW): moment r x F on m."""
    return {"disturbance": np.array([strength, 0.0, 0.0, 0.0, TOW_POINT_BELOW * strength, 0.0])}


def qbar_s(airspeed: np.ndarray, params: FixedWingParams) -> np.ndarray:
    """Dynamic pressure times wing area [N]."""
    return 0.5 * params.rho * airspeed**2 * params.S


def _force_x_on_drag(condition, flight, params):
    """Drag change of a 1 N body force along +x."""
    force = 1.0 / qbar_s(condition.airspeed, params)
    return body_to_lift_drag(force, 0.0 * force, condition.alpha)[1]


def _alphadot_term(condition, flight, params):
    """Pitching-moment change of C_m_alphadot = -1, a downwash lag's sign."""
    return -differentiate(flight.time, condition.alpha) * params.c / (2.0 * condition.airspeed)


def _delay_term(condition, flight, params):
    """Pitching-moment change of a 1 s delay of the elevator, to first order."""
    return -params.derivative("Cm_elevator") * differentiate(flight.time, condition.elevator)


PULL_POINT = (1500.0, 400.0, 0.0)
"""NED point [m] the pull towards a fixed point acts towards: on the ground, 400 m east of
the middle of the flight's track (which runs north from the origin, 100 m up)."""


class PullTowardsPoint(LeafSystem):
    """A force of ``magnitude`` [N] (a constant, or a function of the time [s]) towards
    the NED ``point`` [m] (a tether to an anchor), applied at the body point
    ``attachment`` [m, FRD from the centre of gravity; zero: at the centre of gravity,
    no moment], as the plant's body-axis external wrench (force, then its moment
    ``attachment x force``); input the plant's state (position NED, quaternion, ...)."""

    def __init__(self, magnitude: float | Callable[[float], float], point=PULL_POINT,
                 attachment=(0.0, 0.0, 0.0)):
        super().__init__()
        self._magnitude = magnitude if callable(magnitude) else (lambda t: magnitude)
        self._point = np.asarray(point, dtype=float)
        self._attachment = np.asarray(attachment, dtype=float)
        self._state = self.DeclareVectorInputPort("state", 13)
        self.DeclareVectorOutputPort("wrench", 6, self._wrench)

    def _wrench(self, context, output: BasicVector) -> None:
        x = self._state.Eval(context)
        towards = self._point - x[:3]
        body = np.asarray(quat_to_rotmat(x[3:7])).T @ (towards / np.linalg.norm(towards))
        force = self._magnitude(context.get_time()) * body
        output.SetFromVector(np.concatenate([force, np.cross(self._attachment, force)]))


def pull_towards_point(magnitude: float | Callable[[float], float], point=PULL_POINT,
                       attachment=(0.0, 0.0, 0.0)):
    """Fly options (``extend``): a pull of ``magnitude`` [N] (or a function of the time)
    towards the NED ``point`` [m], applied at the body point ``attachment`` [m, FRD]
    (:class:`PullTowardsPoint`), on the plant's external wrench."""
    def extend(builder, ports):
        pull = builder.AddNamedSystem("pull", PullTowardsPoint(magnitude, point, attachment))
        builder.Connect(ports["state"], pull.get_input_port(0))
        builder.Connect(pull.get_output_port(0),
                        ports["state"].get_system().GetInputPort("external_wrench"))
    return {"extend": extend}


def _pull_on_side_force(condition, flight, params):
    """Side-force change of a 1 N pull towards :data:`PULL_POINT` along a flight's truth."""
    path = np.column_stack([flight["pn"], flight["pe"], flight["pd"]])
    towards = unit_vectors_towards(path, np.array([PULL_POINT]))[:, 0, :]
    rotation = euler_to_rotmat(np.array([flight["roll"], flight["pitch"], flight["yaw"]]))
    body = np.einsum("ijn,in->jn", rotation, towards)
    return body[1] / qbar_s(condition.airspeed, params)


TENSION_BAND = (0.02, 0.5)
"""Frequency band [Hz] of the tether tension's slow variation."""
TENSION_NOISE = 0.05
"""Standard deviation of the logged tension's noise at strength 1 [N] (a load cell)."""


@functools.cache
def _tension_sines() -> tuple[np.ndarray, np.ndarray]:
    """Frequencies [Hz] and phases [rad] of :func:`tether_tension`'s sinusoids."""
    rng = np.random.default_rng(4242)
    return rng.uniform(*TENSION_BAND, 8), rng.uniform(0.0, 2.0 * np.pi, 8)


def tether_tension(t) -> np.ndarray:
    """A tether's tension at strength 1 [N]: eight sinusoids in :data:`TENSION_BAND`, of
    fixed random phases (the same on every flight, like the excitation), unit standard
    deviation about a mean of 3, so that the tether stays taut."""
    frequency, phase = _tension_sines()
    t = np.atleast_1d(np.asarray(t, dtype=float))
    return 3.0 + np.sin(2.0 * np.pi * frequency[:, None] * t + phase[:, None]).sum(axis=0) / 2.0


def _tether(strength, params):
    """Fly options: a pull of ``strength`` times :func:`tether_tension` [N] along -x body at
    the centre of gravity (C_L -= F sin(alpha) / (qbar S), C_D += F cos(alpha) / (qbar S))."""
    def increment(condition, t):
        force = strength * float(tether_tension(t)[0]) / qbar_s(condition.airspeed, params)
        return (-force * np.sin(condition.alpha), force * np.cos(condition.alpha),
                0.0, 0.0, 0.0, 0.0)
    return {"disturbance": increment}


def _tension_on_drag(condition, flight, params):
    """Drag change of the tether at strength 1."""
    return (tether_tension(flight.time) * np.cos(condition.alpha)
            / qbar_s(condition.airspeed, params))


def _tension_logged(log: FlightLog, strength: float, seed: int) -> FlightLog:
    """The log with the tether's load cell, ``tension`` [N], its noise drawn from ``seed``."""
    noise = strength * TENSION_NOISE * np.random.default_rng(seed).standard_normal(len(log))
    return log.with_measured({"tension": strength * tether_tension(log.time) + noise},
                             {"tension": "N"})


_AIR_DATA = ("pitot_qbar", "pitot_airspeed", "vane_alpha", "vane_beta")


def _air_data_late(log: FlightLog, skew: float) -> FlightLog:
    """The air-data channels (pitot, vanes) logged ``skew`` [s] (whole sample periods)
    late against the IMU: each row holds the air-data sample of that many rows before (the
    first one repeated at the start), as a logger that stamps them late writes them."""
    rows = int(round(skew * log.sample_rate))
    return log.with_measured({n: np.concatenate([np.repeat(log[n][:1], rows),
                                                 log[n][:len(log) - rows]])
                              for n in _AIR_DATA})


def _skew_term(condition, flight, params):
    """Lift change of a 1 s air-data skew, to first order (alpha read late)."""
    return -params.derivative("CL_alpha") * differentiate(flight.time, condition.alpha)


RPM_AIRCRAFT = "aerosonde_mavsim"
"""The aircraft of the campaign's RPM variant: the Aerosonde with an electric motor and a
fixed-pitch propeller (:class:`~drake_uav.vehicles.fixed_wing.MotorPropeller`), whose shaft
speed an ESC reports."""
ELECTRIC_AEROSONDE = "aerosonde_electric"
"""The other aircraft the RPM variant can fly (``rpm_aircraft``): the catalog Aerosonde of
the validation campaign (its aerodynamics, mass and inertia) with the mavsim Aerosonde's
motor and propeller. Cruise at 25 m/s takes about 11 N of thrust (0.8 N on the mavsim
Aerosonde, whose drag polar has no parasitic term), and its C_D varies about 2.6 times
as much over a flight, so an effect of a given share of that variation is larger against
the same sensors' noise."""
RPM_AIRCRAFTS = (RPM_AIRCRAFT, ELECTRIC_AEROSONDE)
RPM_NOISE = 3.0
"""Standard deviation of the logged shaft speed's noise [rad/s] (about 30 rev/min: an
ESC's electrical-period count at a few thousand rev/min)."""


RPM_MODES = ("fitted", "table")
"""How the RPM variant's job takes the thrust: C_T(J) fitted with the drag, or the flown
propeller's declared table (:func:`propeller_table`)."""


def campaign_aircraft(name: str) -> FixedWingParams:
    """The aircraft a campaign flies, by name: a catalog aircraft
    (:func:`~drake_uav.vehicles.loading.load_fixed_wing`) or :data:`ELECTRIC_AEROSONDE`.

    Parameters
    ----------
    name : str
        The aircraft's name.

    Returns
    -------
    FixedWingParams
        Its parameters.

    Raises
    ------
    ValueError
        For a name that is neither (from
        :func:`~drake_uav.vehicles.loading.load_fixed_wing`).
    """
    if name == ELECTRIC_AEROSONDE:
        return dataclasses.replace(load_fixed_wing("aerosonde"), name=ELECTRIC_AEROSONDE,
                                   propulsion=load_fixed_wing(RPM_AIRCRAFT).propulsion)
    return load_fixed_wing(name)


def propeller_table(params: FixedWingParams) -> PropellerTable:
    """The declared table of the aircraft's propeller (a maker's data): C_T and C_Q of its
    :class:`~drake_uav.vehicles.fixed_wing.MotorPropeller` at J = 0, 0.1, ..., 1."""
    prop = params.propulsion
    j = np.linspace(0.0, 1.0, 11)
    return PropellerTable(prop.diameter, j,
                          coefficient_polynomial(j, (prop.C_T0, prop.C_T1, prop.C_T2)),
                          coefficient_polynomial(j, (prop.C_Q0, prop.C_Q1, prop.C_Q2)),
                          f"{params.name} propeller")


def shaft_speed_logged(log: FlightLog, params: FixedWingParams, seed: int) -> FlightLog:
    """The log with ``motor_speed`` [rad/s], the propeller's speed along the flight's truth
    (true airspeed, throttle as the motor saw it) with :data:`RPM_NOISE` drawn from
    ``seed``: what an ESC's telemetry or an RPM sensor writes."""
    speed = params.propulsion.propeller_speed(log["airspeed"], log["throttle"], params.rho)
    rng = np.random.default_rng([seed, 0x52504D])
    return log.with_measured({"motor_speed": speed + RPM_NOISE * rng.standard_normal(len(log))},
                             {"motor_speed": "rad/s"})


FLIGHT_DURATION = 120.0
"""Length of a campaign flight [s] unless the scenario's ``duration`` says otherwise."""
MIN_DURATION = 30.0
"""Shortest flight [s] the scenario accepts."""
EXCITATIONS = ("multisine", "multisine_throttle")
"""Excitations a campaign flight can fly."""


def _index(coefficient: str) -> int:
    return COEFFICIENTS.index(coefficient)


INJECTED: dict[str, Injection] = {
    "propwash_drag": Injection(
        "thrust_propwash", "CD", lambda c, f, p: c.thrust_coefficient,
        _increment(_index("CD"), lambda c: c.thrust_coefficient)),
    "stall_onset": Injection(
        "stall_onset", "CL", lambda c, f, p: -c.alpha**3,
        _increment(_index("CL"), lambda c: -c.alpha**3)),
    "elevator_roll": Injection(
        "control_cross_coupling", "Cl", lambda c, f, p: c.elevator,
        _increment(_index("Cl"), lambda c: c.elevator)),
    "elevator_squared": Injection(
        "control_nonlinearity", "Cm", lambda c, f, p: c.elevator**2,
        _increment(_index("Cm"), lambda c: c.elevator**2)),
    "roll_yaw_rate_pitch": Injection(
        "rate_coupling", "Cm", lambda c, f, p: c.p * c.r * (p.b / (2 * c.airspeed)) ** 2,
        lambda k, p: _increment(_index("Cm"), lambda c: c.p * c.r * (
            p.b / (2 * c.airspeed)) ** 2)(k, p)),
    "alphadot_pitch": Injection(
        "unsteady_alphadot", "Cm", _alphadot_term,
        lambda k, p: {"aircraft": p.with_derivatives(Cm_alphadot=-k)}),
    "servo_delay": Injection(
        "actuator_time_delay", "Cm", _delay_term,
        lambda k, p: {"actuator_delay": k}, strength_step=0.01),
    "tow_force": Injection(
        "constant_body_force", "CD", _force_x_on_drag, _body_force_x),
    "tow_below_cg": Injection(
        "force_body_x_off_cg", "CD", _force_x_on_drag, _tow_below_cg),
    "drag_drift": Injection(
        "coefficient_drift", "CD", _share_of_flight, _drift(_index("CD")),
        over_flight=True),
    "air_data_skew": Injection(
        "air_data_time_skew", "CL", _skew_term, sensors=_air_data_late, strength_step=0.01),
    "pull_to_point": Injection(
        "force_towards_point", "CY", _pull_on_side_force,
        lambda strength, params: pull_towards_point(strength), point=PULL_POINT),
    "logged_tension": Injection(
        "logged:tension", "CD", _tension_on_drag, _tether, logged=_tension_logged),
}
"""The effects of the campaign by key. Strength 1 is: C_D += T_c (propwash); C_L -= alpha^3;
C_l += delta_e; C_m += delta_e^2; C_m += p_hat r_hat; C_m_alphadot = -1 (a downwash lag's
sign); a 1 s elevator and throttle delay; a 1 N tow force along +x body; the same force
0.3 m below the centre of gravity (a vector effect: C_L, C_D and C_m); C_D growing by 1 over
the flight; pitot and vanes logged 1 s late against the IMU (a time skew between channel
groups: a calibration error the data-compatibility check names); a 1 N pull towards the
fixed point :data:`PULL_POINT` at the centre of gravity (a vector effect on C_L, C_D and
C_Y, its size measured on C_Y); a tether pulling along -x body with a tension of mean 3 N
and standard deviation 1 N, logged by a load cell as the extra channel ``tension``
(expected: the logged channel, ``logged:tension``)."""


def aero_condition(flight: FlightLog, params: FixedWingParams) -> AeroCondition:
    """The aerodynamic condition along a flight's truth channels (the plant's surfaces)."""
    airspeed = flight["airspeed"]
    thrust = params.propulsion.thrust_torque(airspeed, flight["throttle"], params.rho)[0]
    return AeroCondition(airspeed, flight["alpha"], flight["beta"], flight["p"], flight["q"],
                         flight["r"], flight["elevator"], flight["aileron"], flight["rudder"],
                         thrust_coefficient=thrust / qbar_s(airspeed, params))


def true_coefficients(flight: FlightLog, condition: AeroCondition) -> dict[str, np.ndarray]:
    """The catalog model's coefficients along the true trajectory (the truth channels of a
    flight of :func:`~drake_uav.diagrams.fly`; ``condition`` from :func:`aero_condition`)."""
    lift, drag = body_to_lift_drag(flight["CX"], flight["CZ"], condition.alpha)
    return {"CL": lift, "CD": drag, "CY": flight["CY"], "Cl": flight["Cl"],
            "Cm": flight["Cm"], "Cn": flight["Cn"]}


def unit_strength_ratio(injection: Injection, flight: FlightLog, params: FixedWingParams
                        ) -> float:
    """``std(coefficient) / std(term at strength 1)`` over a flight's truth: the strength
    that gives a size of 1."""
    condition = aero_condition(flight, params)
    term = np.broadcast_to(injection.term(condition, flight, params), flight.time.shape)
    return float(np.std(true_coefficients(flight, condition)[injection.coefficient])
                 / np.std(term))


@functools.cache
def _calibration(turbulence: str, duration: float, excitation: str,
                 aircraft: str = "aerosonde") -> dict[str, float]:
    """Median unit-strength ratio of every injection over the calibration flights of
    ``duration`` [s] and ``excitation`` with the ``aircraft`` (:func:`campaign_aircraft`)."""
    params = campaign_aircraft(aircraft)
    flights = [fly(params, turbulence=turbulence, seed=s, duration=duration,
                   excitation=excitation) for s in CALIBRATION_SEEDS]
    return {key: float(np.median([unit_strength_ratio(injection, f, params) for f in flights]))
            for key, injection in INJECTED.items()}


def _strength(injection: Injection, key: str, size: float, turbulence: str,
              duration: float, excitation: str, aircraft: str = "aerosonde") -> float:
    strength = size * _calibration(turbulence, duration, excitation, aircraft)[key]
    if injection.strength_step:
        strength = max(round(strength / injection.strength_step), 1) * injection.strength_step
    return strength


def calibrated_strength(key: str, size: float, turbulence: str = "light",
                        duration: float = FLIGHT_DURATION, excitation: str = "multisine"
                        ) -> float:
    """The strength of the effect ``key`` of :data:`INJECTED` that gives ``size`` on the
    calibration flights of ``turbulence``, ``duration`` [s] and ``excitation`` (the one a
    campaign flight of these settings carries)."""
    return _strength(INJECTED[key], key, size, turbulence, duration, excitation)


def _realised_size(injection: Injection, flight: FlightLog, params: FixedWingParams,
                   strength: float) -> float:
    return strength / unit_strength_ratio(injection, flight, params)


@register_scenario("discovery")
def discovery(seed: int, params: dict) -> dict:
    """One flight with an undeclared effect (or none), then the main job.

    Parameters (defaults): ``effect`` (a key of :data:`INJECTED` or "none"), ``size``
    (0.3, share of the coefficient's variation), ``suite`` ("default" or "research"),
    ``turbulence`` ("light"), ``duration`` (:data:`FLIGHT_DURATION` s) and ``excitation``
    ("multisine"; "multisine_throttle" also moves the throttle,
    :func:`~drake_uav.diagrams.identification_flight.default_excitation`), the sizes being
    calibrated on flights of the same length and excitation, ``min_folds`` (the evidence rule's,
    :attr:`~drake_uav.identification.discovery.result.EvidenceRule.min_folds`: how many of the
    five folds an effect must improve; for studies of the rule), ``rpm`` (False; "fitted"
    or True flies :data:`RPM_AIRCRAFT` and logs its propeller's shaft speed,
    :func:`shaft_speed_logged`, and the job fits C_T(J) with the drag; "table" gives the
    job the propeller's declared table, :func:`propeller_table`, which fixes the thrust
    independently of the drag), ``rpm_aircraft`` (:data:`RPM_AIRCRAFT`; or
    :data:`ELECTRIC_AEROSONDE`, the validation's Aerosonde with that motor and propeller).

    Metrics: ``found`` (comma-separated findings), ``exact``, ``partial``, ``missed``,
    ``false_findings``, ``size_realised``, ``strength``; for an aerodynamic effect the
    held-out RMS of its coefficient ``rms_before`` / ``rms_after``, its noise floor
    ``floor`` and ``excess_explained`` (NaN when the error was at the floor); ``tied``:
    the effect was not found but the report names it as a near-tied alternative of a
    finding (:func:`~drake_uav.identification.assessment.near_ties.near_ties`: the flight
    cannot tell them apart); ``family``: found exactly or as a member of the family a
    finding names (:func:`found_as_family`); for a force towards a point, ``point_error``
    and ``point_sigma`` (:func:`_point_error`).
    """
    key = params.get("effect", "none")
    if key != "none" and key not in INJECTED:
        raise ValueError(f"discovery: effect {key!r} unknown (known: none, {', '.join(INJECTED)})")
    suite = params.get("suite", "default")
    if suite not in SUITES:
        raise ValueError(f"discovery: suite {suite!r} unknown (known: {', '.join(SUITES)})")
    size = float(params.get("size", 0.3))
    turbulence = params.get("turbulence", "light")
    duration = float(params.get("duration", FLIGHT_DURATION))
    excitation = params.get("excitation", "multisine")
    if excitation not in EXCITATIONS:
        raise ValueError(f"discovery: excitation {excitation!r} unknown (known: "
                         f"{', '.join(EXCITATIONS)})")
    if not duration >= MIN_DURATION:
        raise ValueError(f"discovery: duration {duration:g} s is too short for the main job's "
                         f"folds and held-out tail; fly at least {MIN_DURATION:g} s")
    rpm = params.get("rpm", False)
    rpm = "fitted" if rpm is True else rpm
    if rpm and rpm not in RPM_MODES:
        raise ValueError(f"discovery: rpm {rpm!r} unknown (known: {', '.join(RPM_MODES)})")
    aircraft = params.get("rpm_aircraft", RPM_AIRCRAFT) if rpm else "aerosonde"
    if rpm and aircraft not in RPM_AIRCRAFTS:
        raise ValueError(f"discovery: rpm_aircraft {aircraft!r} unknown (known: "
                         f"{', '.join(RPM_AIRCRAFTS)})")
    catalog = campaign_aircraft(aircraft)
    options = {"aircraft": catalog, "turbulence": turbulence, "seed": seed,
               "duration": duration, "excitation": excitation,
               "sensors": SUITES[suite](catalog.rho)}
    injection = INJECTED.get(key)
    strength = 0.0
    if injection is not None:
        strength = _strength(injection, key, size, turbulence, duration, excitation, aircraft)
        options.update(injection.fly_options(strength, catalog, duration))
    log = fly(**options)
    if rpm:
        log = shaft_speed_logged(log, catalog, seed)
    truth = log
    if injection is not None and injection.sensors is not None:
        log = injection.sensors(log, strength)
    if injection is not None and injection.logged is not None:
        log = injection.logged(log, strength, seed)
    rule = EvidenceRule(min_folds=int(params.get("min_folds", EvidenceRule.min_folds)))
    table = {"propeller": propeller_table(catalog)} if rpm == "table" else {}
    run = identify(measured_only(log), catalog, seed=seed, rule=rule, **table)
    found = list(run.findings)
    expected = injection.expected if injection else None
    metrics = {"found": ",".join(found), "false_findings": sum(n != expected for n in found),
               "strength": strength}
    if injection is None:
        return metrics | {"any_finding": bool(found)}
    metrics |= {"exact": found == [expected], "partial": expected in found and len(found) > 1,
                "missed": expected not in found,
                "tied": expected not in found and expected in _tied_alternatives(run),
                "family": found_as_family(run, expected),
                "size_realised": _realised_size(injection, truth, catalog, strength)}
    if injection.sensors is None:
        floor = held_out_noise_floor(run.samples, run.discovery, catalog)[injection.coefficient]
        explained = floor.excess_explained
        metrics |= {"rms_before": floor.before, "rms_after": floor.after, "floor": floor.floor,
                    "excess_explained": math.nan if explained is None else explained}
    if injection.point is not None:
        metrics |= _point_error(run, injection)
    return metrics


def found_as_family(run, expected: str) -> bool:
    """Whether the report points at ``expected`` exactly or as a member of a family.

    True when the findings are exactly ``expected``, or when every finding is ``expected``
    or names it among the members of its family (its aliases and near ties,
    :func:`~drake_uav.identification.assessment.families.families`): the report then names
    the family the effect belongs to and lists it, and names nothing outside it.

    Parameters
    ----------
    run : IdentificationRun
        The main job's result.
    expected : str
        The finding that names the injected effect.

    Returns
    -------
    bool
        Found exactly or as a family.
    """
    found = list(run.findings)
    if found == [expected]:
        return True
    members = ({} if run.discovery is None else
               {f.effect: f.member_names for f in families(run.discovery)})
    return bool(found) and all(name == expected or expected in members.get(name, ())
                               for name in found)


def _tied_alternatives(run) -> set[str]:
    """Effects the report names as near-tied alternatives of a finding."""
    if run.discovery is None:
        return set()
    return {e.effect for tie in near_ties(run.discovery) for e in tie.alternatives}


def _point_error(run, injection: Injection) -> dict:
    """``point_error`` [m]: the distance from the point the finding located to the true
    one, and ``point_sigma`` [m]: the largest standard deviation of its coordinates (NaN
    when the effect was not found)."""
    found = next((f for f in run.discovery.found if f.name == injection.expected), None)
    if found is None or "p_n" not in found.parameters:
        return {"point_error": math.nan, "point_sigma": math.nan}
    located = [found.parameters[f"p_{axis}"] for axis in "ned"]
    return {"point_error": float(np.linalg.norm(np.subtract([p for p, _ in located],
                                                            injection.point))),
            "point_sigma": max(sigma for _, sigma in located)}


def measured_only(log: FlightLog) -> FlightLog:
    """The log as an autopilot would write it: measured channels, no truth, no metadata
    (no true sensor noise, no command rate)."""
    names = log.measured_names
    return FlightLog(log.time, {n: log[n] for n in names}, units={n: log.unit(n) for n in names})
