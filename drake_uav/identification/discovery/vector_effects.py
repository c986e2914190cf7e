"""Vector effects: one force along a direction the log defines, tested jointly on every
coefficient it moves.

A vector effect is a force ``F(t) = m(t) d(t)`` acting at a body point ``r``: ``d`` a unit
vector the log defines (a body axis; against the air-relative velocity, i.e. along the
drag; against the GPS velocity; towards a fixed NED point; a logged vector), ``m`` a
fitted constant [N] or a fitted gain times a logged channel (a load cell, a current).
In equation error it adds ``F / (qbar S)`` to the force coefficients (``C_X, C_Y, C_Z``,
hence ``C_L, C_D, C_Y``) and, when it acts away from the reference point, ``r x F`` over
``qbar S b`` (``qbar S c``) to ``C_l, C_n`` (``C_m``). With ``u = m r`` the effect is
linear in its few parameters ``(m, u_x, u_y, u_z)``, shared by all those coefficients.

They are estimated jointly with every coefficient's own columns: the stacked,
bias-compensated normal equations of the coefficients, each weighted by the inverse of
its residual's long-run variance per sample, solved for the shared parameters by block
elimination of each coefficient's columns (the equation-error estimation of several
outputs sharing parameters, Klein & Morelli 2006, ch. 5 and 6; Frisch-Waugh-Lovell).
One partial F-test with as many degrees of freedom as parameters, blocked
cross-validation of the weighted sum of the coefficients' held-out errors and the BIC
decide (:class:`~drake_uav.identification.discovery.result.EvidenceRule`, in the same
family-wise Bonferroni count as the per-coefficient candidates); the held-out rules
(:class:`~drake_uav.identification.discovery.result.HeldOutCheck`) then decide coefficient by
coefficient. An accepted effect enters each coefficient it is kept on as one column, its
jointly estimated shape; its reported parameters come from a joint refit against the
final fits, with a sandwich covariance over all the coefficients' scores.

A force towards a point nobody gave (``vector_effect("towards_point")``, in the default
library as ``force_towards_point``) is nonlinear in the point: in each round the point is
located by the profile of the joint fit over a grid of candidate points around the
flight path, refined locally; the effect is tested at the best grid point with its
p-value multiplied by the number of candidate points (Bonferroni over the grid,
:mod:`~drake_uav.identification.discovery.fitted_point`) and carried on at the refined point, and
the point's parameters ``p_n, p_e, p_d`` [m, NED] are reported with their sigmas (the
force linearised about it, one Gauss-Newton step). A negative magnitude is a force away
from the point.

Competition with the per-coefficient named effects: a round's passing candidates are
compared by the held-out error they remove, summed over the coefficients they move in
units of each coefficient's own error (a per-coefficient effect: over the coefficients it
passed on). A force acting behind the centre of gravity then comes out as one effect on
``C_Y`` and ``C_n``, not as a side force on ``C_Y`` plus a yawing-moment term elsewhere.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from drake_uav.identification.discovery.coefficient_design import columns_and_jacobians
from drake_uav.identification.discovery.effects import EXTERNAL_FORCE
from drake_uav.identification.discovery.evidence import (
    Candidate,
    CandidateColumns,
    JointBlock,
    JointEvidence,
    joint_solve,
    nonzero_columns,
    score_jointly,
)
from drake_uav.identification.discovery.fitted_point import (
    PointFit,
    PointProfile,
    ProfileKernels,
    ned_to_body,
    positions,
    towards,
    towards_gradient,
)
from drake_uav.identification.discovery.result import Evidence, EvidenceRule, FoundEffect
from drake_uav.identification.samples.aero_samples import (
    ATTITUDE,
    GPS_POSITION,
    GPS_VELOCITY,
    AeroSamples,
)
from drake_uav.identification.statistics.errors_in_variables import (
    long_run_covariance,
)
from drake_uav.identification.statistics.residuals import effective_sample_size
from drake_uav.model.air_data import velocity_from_air_data
from drake_uav.model.coefficients import COEFFICIENTS, body_to_lift_drag
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["VectorEffect", "JointSearch", "vector_effect",
           "vector_effect_library", "DIRECTIONS", "force_coefficient_change",
           "far_point_as_direction", "FAR_OUTSIDE"]

_MOMENT_AXIS = {"Cl": 0, "Cm": 1, "Cn": 2}
_FORCES = ("CL", "CD", "CY")
_ARMS = ("Fr_x", "Fr_y", "Fr_z")
"""The moment parameters ``u = m r`` [N m] (their column is ``e_j x F``)."""
_SHIFTS = ("Fp_n", "Fp_e", "Fp_d")
"""The linearised point's parameters ``m dP`` [N m] (their column is the force's change
with the point, per metre)."""

Direction = Callable[[AeroSamples], np.ndarray]
"""``direction(samples) -> (N, 3)`` body-axis unit vectors."""


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-9)


def _body_axis(axis: int) -> Direction:
    return lambda samples: np.broadcast_to(np.eye(3)[axis], (len(samples), 3))


def _against_air_velocity(samples: AeroSamples) -> np.ndarray:
    c = samples.condition
    return -np.column_stack(velocity_from_air_data(1.0, c.alpha, c.beta))


def _against_ground_velocity(samples: AeroSamples) -> np.ndarray:
    v = np.column_stack([samples.signals[s] for s in GPS_VELOCITY])
    return -ned_to_body(samples, _unit(v))


def _towards(point: Sequence[float]) -> Direction:
    return lambda samples: towards(samples, point)


def _logged(names: Sequence[str], frame: str) -> Direction:
    def direction(samples):
        v = _unit(np.column_stack([samples.signals[s] for s in names]))
        return v if frame == "body" else ned_to_body(samples, v)
    return direction


DIRECTIONS = {
    "body_x": "along the body x axis",
    "body_y": "along the body y axis",
    "body_z": "along the body z axis",
    "air_velocity": "against the air-relative velocity (a drag)",
    "ground_velocity": "against the GPS velocity",
    "towards_point": "towards a fixed NED point (given, or located by the data)",
    "logged": "along a logged vector",
}
"""Direction kinds -> what the unit vector is (a negative magnitude reverses it)."""


@dataclasses.dataclass(frozen=True)
class VectorEffect:
    """A force along a direction the log defines (see the module docstring).

    Attributes
    ----------
    name : str
        Its name in the findings.
    explanation : str
        One line on the physics.
    direction : str
        Kind, a key of :data:`DIRECTIONS`.
    unit_vectors : callable or None
        The direction's unit vectors on samples; None for a point not located yet
        (:attr:`fitted`).
    signals : tuple of str
        ``AeroSamples.signals`` the direction needs.
    magnitude : str or None
        ``AeroSamples.signals`` channel the force is proportional to (None: constant).
    lever_arm : bool
        Fit the application point (its moment on ``C_l, C_m, C_n``); False: at the
        reference point (the centre of gravity).
    point : (float, float, float) or None
        The NED point [m] of a ``"towards_point"`` direction (None: not located yet).
    searched : int
        Candidate points the point was chosen from (0: given; see
        :mod:`~drake_uav.identification.discovery.fitted_point`).
    linearised : bool
        With the point's shift parameters ``Fp_n, Fp_e, Fp_d`` (its uncertainty).

    Examples
    --------
    >>> wind = vector_effect("ground_velocity")
    >>> wind.direction, wind.lever_arm
    ('ground_velocity', False)
    """

    name: str
    explanation: str
    direction: str
    unit_vectors: Direction | None
    signals: tuple[str, ...] = ()
    magnitude: str | None = None
    lever_arm: bool = False
    point: tuple[float, float, float] | None = None
    searched: int = 0
    linearised: bool = False

    def available(self, samples: AeroSamples) -> bool:
        """Whether the samples carry every signal the effect needs.

        Parameters
        ----------
        samples : AeroSamples
            The samples.

        Returns
        -------
        bool
            True when the effect can be tested on them.
        """
        needed = self.signals + ((self.magnitude,) if self.magnitude else ())
        return all(s in samples.signals for s in needed)

    def candidate(self, params: FixedWingParams) -> Candidate:
        """The effect as a plant-agnostic candidate of the evidence rule.

        Its parameters are shared by every coefficient it moves, tested jointly.

        Parameters
        ----------
        params : FixedWingParams
            The aircraft the columns are computed for.

        Returns
        -------
        Candidate
            The joint candidate.
        """
        return Candidate(self.name, self.explanation, COEFFICIENTS,
                         lambda samples, k: self.columns(samples, params, k),
                         parameters=self.parameters, joint=True, searched=self.searched,
                         origin=self.physical_origin)

    @property
    def physical_origin(self) -> str:
        """Its physical origin: :data:`~drake_uav.identification.discovery.effects.
        EXTERNAL_FORCE`, as every force effect's."""
        return EXTERNAL_FORCE

    @property
    def fitted(self) -> bool:
        """The point of a ``"towards_point"`` direction is located by the data."""
        return self.direction == "towards_point" and (self.point is None or self.searched > 0)

    def at(self, point: Sequence[float], searched: int) -> VectorEffect:
        """This effect towards ``point``, chosen from ``searched`` candidates.

        Parameters
        ----------
        point : sequence of float
            The point [m, NED].
        searched : int
            Number of candidate points it was chosen from.

        Returns
        -------
        VectorEffect
            The located effect.
        """
        point = tuple(float(x) for x in point)
        return dataclasses.replace(self, unit_vectors=_towards(point), point=point,
                                   searched=searched)

    @property
    def parameters(self) -> tuple[str, ...]:
        """Linear parameters: ``F`` the magnitude [N] (or gain [N per channel unit]); with a
        lever arm, ``Fr_x, Fr_y, Fr_z`` = F times the application point [N m]; linearised,
        ``Fp_n, Fp_e, Fp_d`` = F times the point's shift [N m]."""
        return ("F", *(_SHIFTS if self.linearised else ()),
                *(_ARMS if self.lever_arm else ()))

    def _forces(self, view: AeroSamples) -> dict[str, np.ndarray]:
        """Body-axis force (N, 3) per unit of each force parameter."""
        forces = {"F": np.array(self.unit_vectors(view), dtype=float)}
        if self.linearised:
            gradient = towards_gradient(view, self.point)
            forces.update((n, gradient[:, :, j]) for j, n in enumerate(_SHIFTS))
        if self.magnitude:
            size = np.asarray(view.signals[self.magnitude], dtype=float)[:, None]
            forces = {n: f * size for n, f in forces.items()}
        return forces

    def columns(self, samples: AeroSamples, params: FixedWingParams,
                coefficient: str) -> dict[str, np.ndarray]:
        """Regressor columns of every parameter on ``coefficient`` (zeros where it does not enter).

        Parameters
        ----------
        samples : AeroSamples
            The samples.
        params : FixedWingParams
            The aircraft (mass, wing area and reference lengths that turn a force into a
            coefficient).
        coefficient : str
            The coefficient.

        Returns
        -------
        dict of str to numpy.ndarray
            Parameter name -> (N,) column.
        """
        view = samples.aligned(coefficient)
        zero = np.zeros(len(view))
        out = dict.fromkeys(self.parameters, zero)
        if coefficient not in _FORCES and not (coefficient in _MOMENT_AXIS and self.lever_arm):
            return out
        forces = self._forces(view)
        if coefficient in _FORCES:
            out.update((name, force_coefficient_change(view, params, coefficient, force))
                       for name, force in forces.items())
        else:
            per_unit = 1.0 / (view.dynamic_pressure * params.S)
            axis = _MOMENT_AXIS[coefficient]
            length = params.c if coefficient == "Cm" else params.b
            for j, name in enumerate(_ARMS):
                out[name] = np.cross(np.eye(3)[j], forces["F"])[:, axis] * per_unit / length
        return out


def force_coefficient_change(view: AeroSamples, params: FixedWingParams, coefficient: str,
                             force: np.ndarray) -> np.ndarray:
    """The change of a force coefficient by a body-axis force.

    Parameters
    ----------
    view : AeroSamples
        The samples as ``coefficient`` sees them (``samples.aligned(coefficient)``).
    params : FixedWingParams
        The aircraft (its wing area).
    coefficient : str
        ``CL``, ``CD`` or ``CY``.
    force : numpy.ndarray of shape (N, 3)
        The force in body axes [N].

    Returns
    -------
    numpy.ndarray of shape (N,)
        The coefficient's change: the force over ``qbar S`` along its axis.
    """
    cx, cy, cz = (force / (view.dynamic_pressure * params.S)[:, None]).T
    lift, drag = body_to_lift_drag(cx, cz, view.condition.alpha)
    return {"CL": lift, "CD": drag, "CY": cy}[coefficient]


FAR_OUTSIDE = 2.0
"""A located point farther from the flight path than this many times the flight volume's
size (the diagonal of the path's bounding box; the farthest candidate points,
:data:`~drake_uav.identification.discovery.fitted_point.FARTHEST`, lie as far) is reported
as a fixed direction (:func:`far_point_as_direction`)."""


def far_point_as_direction(found: FoundEffect, path: np.ndarray) -> FoundEffect:
    """A force towards a located point, reported as a fixed NED direction when the point is
    far outside the flight volume or its uncertainty exceeds its distance.

    Seen from a flight path, a point far beyond it (more than :data:`FAR_OUTSIDE` times the
    flight volume's size from the path) is a direction that hardly turns, and a point whose
    uncertainty (the norm of its coordinates' sigmas) exceeds its distance from the path is
    not located at all: the data tell the direction, not the point. The finding is then
    ``force_fixed_direction...`` along the direction from the path's centre towards the
    point, ``azimuth`` (from north, towards east) and ``elevation`` (above the horizon)
    [rad], their sigma the point's uncertainty across the line of sight over its distance;
    the point's parameters are left out.

    Parameters
    ----------
    found : FoundEffect
        A finding of a force towards a located point, with ``p_n, p_e, p_d`` (and their
        sigmas) among its parameters.
    path : numpy.ndarray of shape (N, 3)
        The flight path [m, NED].

    Returns
    -------
    FoundEffect
        ``found`` itself when the point is located, else the fixed direction.
    """
    if not all(f"p_{a}" in found.parameters for a in "ned"):
        return found
    point = np.array([found.parameters[f"p_{a}"][0] for a in "ned"])
    sigma = float(np.linalg.norm([found.parameters[f"p_{a}"][1] for a in "ned"]))
    distance = float(np.min(np.linalg.norm(path - point, axis=1)))
    size = float(np.linalg.norm(np.ptp(path, axis=0)))
    far = distance > FAR_OUTSIDE * size
    if not far and sigma <= distance:
        return found
    centre = 0.5 * (path.min(axis=0) + path.max(axis=0))
    line = point - centre
    reach = max(float(np.linalg.norm(line)), 1e-9)
    north, east, down = line / reach
    spread = min(sigma / reach, np.pi)
    parameters = {n: v for n, v in found.parameters.items()
                  if not n.startswith(("p_", "Fp_"))}
    parameters |= {"azimuth": (float(np.arctan2(east, north)), spread),
                   "elevation": (float(np.arctan2(-down, np.hypot(north, east))), spread)}
    why = (f"{distance:.0f} m from the flight path, far outside its {size:.0f} m" if far else
           f"{distance:.0f} m from the flight path with an uncertainty of {sigma:.0f} m")
    explanation = (found.explanation.replace(
        "towards a fixed NED point located by the data", "along a fixed NED direction")
        + f" (the point the data located lies {why}: a direction, not a point)")
    return dataclasses.replace(found, name=found.name.replace("towards_point", "fixed_direction"),
                               explanation=explanation, parameters=parameters)


def vector_effect(direction: str, *, magnitude: str | None = None, lever_arm: bool = False,
                  point: Sequence[float] | None = None, logged: Sequence[str] = (),
                  frame: str = "body", name: str | None = None) -> VectorEffect:
    """A :class:`VectorEffect` of a direction kind (:data:`DIRECTIONS`).

    Parameters
    ----------
    direction : str
        A key of :data:`DIRECTIONS`.
    magnitude : str, optional
        A logged channel the force is proportional to (None: constant).
    lever_arm : bool
        Fit the application point.
    point : sequence of float, optional
        The NED point [m] of ``"towards_point"`` (None: located by the data in each round,
        :mod:`~drake_uav.identification.discovery.fitted_point`).
    logged : sequence of str
        The three channels of ``"logged"``.
    frame : str
        Their frame, ``"body"`` or ``"ned"``.
    name : str, optional
        The effect's name (None: from the direction and the options).

    Returns
    -------
    VectorEffect
        The effect.

    Raises
    ------
    ValueError
        For an unknown direction, or ``"logged"`` without three channels and a frame.
    """
    if direction not in DIRECTIONS:
        raise ValueError(f"direction: one of {', '.join(DIRECTIONS)}, got {direction!r}")
    if direction.startswith("body_"):
        unit, signals = _body_axis("xyz".index(direction[-1])), ()
    elif direction == "air_velocity":
        unit, signals = _against_air_velocity, ()
    elif direction == "ground_velocity":
        unit, signals = _against_ground_velocity, GPS_VELOCITY + ATTITUDE
    elif direction == "towards_point":
        if point is not None and len(point) != 3:
            raise ValueError("towards_point: give the point, NED [m], or None to fit it")
        unit, signals = None if point is None else _towards(point), GPS_POSITION + ATTITUDE
    else:
        if len(logged) != 3 or frame not in ("body", "ned"):
            raise ValueError("logged: give three channels and a frame 'body' or 'ned'")
        unit = _logged(logged, frame)
        signals = tuple(logged) + (ATTITUDE if frame == "ned" else ())
    where = "acting away from the centre of gravity" if lever_arm else "at the centre of gravity"
    size = f"proportional to the logged {magnitude}" if magnitude else "of constant magnitude"
    kind = ("towards_given_point" if direction == "towards_point" and point is not None
            else direction)
    name = name or "_".join(filter(None, ("force", kind, magnitude,
                                          "off_cg" if lever_arm else None)))
    towards_what = DIRECTIONS[direction]
    if direction == "towards_point":
        towards_what = ("towards a fixed NED point located by the data" if point is None
                        else "towards the fixed NED point ({:.0f}, {:.0f}, {:.0f}) m".format(
                            *point))
    return VectorEffect(name, f"a force {size} {towards_what}, {where}", direction, unit,
                        signals, magnitude, lever_arm,
                        None if point is None else tuple(float(x) for x in point))


def vector_effect_library(magnitudes: Sequence[str | None] = (None,),
                          located_point: bool = True) -> list[VectorEffect]:
    """The vector effects the discovery loop tries.

    A force along a body axis at the centre of gravity is the per-coefficient
    ``constant_body_force``: here a body-axis force always has its lever arm. The forces
    against the GPS velocity and towards a point the data locate (``force_towards_point``,
    :mod:`~drake_uav.identification.discovery.fitted_point`) need the GPS in the samples'
    signals. A force towards a located point is also tried away from the centre of gravity
    (a tether on a hook) when its magnitude is a logged channel; of constant magnitude,
    only at the centre of gravity, so that a flight without a logged force is searched as
    the validation campaign measured it (docs/validation.md).

    Parameters
    ----------
    magnitudes : sequence of str or None
        One set of effects per magnitude (None: constant; a name: that logged channel).
    located_point : bool
        Include the force towards a point the data locate.

    Returns
    -------
    list of VectorEffect
        The effects.

    Examples
    --------
    >>> [effect.direction for effect in vector_effect_library(located_point=False)][:3]
    ['body_x', 'body_y', 'body_z']
    """
    out = []
    for magnitude in magnitudes:
        out += [vector_effect(f"body_{a}", magnitude=magnitude, lever_arm=True) for a in "xyz"]
        out += [vector_effect(d, magnitude=magnitude, lever_arm=arm)
                for d in ("air_velocity", "ground_velocity") for arm in (False, True)]
        if located_point:  # away from the c.g. only with a logged magnitude (docstring)
            out += [vector_effect("towards_point", magnitude=magnitude, lever_arm=arm)
                    for arm in ((False, True) if magnitude else (False,))]
    return out


# ----------------------------------------------------------------------------- joint fit


def _twin_at_cg_does_as_well(joint: JointEvidence, passing: Sequence[JointEvidence],
                             margin: float) -> bool:
    """True for a passing force away from the centre of gravity whose twin at the centre
    of gravity (same name without ``_off_cg``) passes too and removes within ``margin`` per
    moment coefficient as much held-out error (:meth:`JointSearch.accept`)."""
    if not joint.effect.lever_arm:
        return False
    twin = joint.effect.name.removesuffix("_off_cg")
    rival = next((j for j in passing if j.effect.name == twin), None)
    moments = sum(k in _MOMENT_AXIS for k in joint.coefficients)
    return rival is not None and joint.total - rival.total <= margin * max(moments, 1)


class JointSearch:
    """The vector effects of one discovery, in every round.

    Their columns, their joint evidence in each round, their acceptance against the
    per-coefficient candidates and their parameters. ``search`` arguments of the methods
    are the discovery's ``_Search`` (its designs, held-out check and sample variants);
    ``bases`` its round bases (design, effective sample size, fold errors, block moments,
    basis).

    Parameters
    ----------
    effects : sequence of VectorEffect
        The effects; those the samples cannot test are left out.
    samples : AeroSamples
        The samples.
    """

    def __init__(self, effects: Sequence[VectorEffect], samples: AeroSamples):
        self.effects = [e for e in effects if e.available(samples)]
        self._train: dict[tuple[VectorEffect, str], tuple[dict, dict]] = {}
        self._accepted: dict[str, VectorEffect] = {}
        """The effects accepted, by name, with the point they were accepted at."""
        self._profiles: dict[VectorEffect, tuple[PointProfile, dict]] = {}

    def evidence(self, joint: Sequence[JointEvidence],
                 coefficients: Sequence[str] | None = None) -> list[Evidence]:
        """One :class:`Evidence` per effect and coefficient.

        The joint statistics with the coefficient's own held-out reduction.

        Parameters
        ----------
        joint : sequence of JointEvidence
            The joint evidence.
        coefficients : sequence of str, optional
            Only these coefficients (None: all).

        Returns
        -------
        list of Evidence
            The per-coefficient evidence.
        """
        return [e for j in joint for e in j.evidence()
                if coefficients is None or e.coefficient in coefficients]

    # -- columns

    def _columns(self, search, effect: VectorEffect, k: str, test: bool = False):
        """(columns, jacobians) of ``effect`` on coefficient ``k`` (training part, or
        the held-out tail), the parameters that do not enter ``k`` left out."""
        key = (effect, k)
        if test or key not in self._train:
            variants = search.test_variants if test else search.pool.variants
            design = (search.tests if test else search.designs)[k]
            own = nonzero_columns(CandidateColumns(*columns_and_jacobians(
                lambda smp: effect.columns(smp, search.pool.params, k), variants,
                design.noise.variance)))
            out = (own.columns, own.jacobians)
            if test:
                return out
            self._train[key] = out
        return self._train[key]

    def training_columns(self, search, effect: VectorEffect, k: str) -> dict[str, np.ndarray]:
        """The columns of ``effect`` on coefficient ``k`` over the training part, those of
        the parameters that do not enter ``k`` left out.

        Parameters
        ----------
        search : object
            The discovery's search state.
        effect : VectorEffect
            An effect whose direction is known (not a point still to locate).
        k : str
            The coefficient.

        Returns
        -------
        dict of str to numpy.ndarray
            Parameter name -> (N,) column.
        """
        return dict(self._columns(search, effect, k)[0])

    def candidates(self, used: set[str]) -> list[VectorEffect]:
        """The effects not tried yet.

        Parameters
        ----------
        used : set of str
            Names of the effects tried.

        Returns
        -------
        list of VectorEffect
            The others.
        """
        return [e for e in self.effects if e.name not in used]

    # -- evidence

    def score(self, search, bases: Mapping, rule: EvidenceRule, n_tests: int,
              used: set[str]) -> list[JointEvidence]:
        """The joint evidence of every vector effect not tried yet.

        An effect towards a point the data locate is tested at the best of its candidate
        points and carried on at the refined one
        (:mod:`~drake_uav.identification.discovery.fitted_point`).

        Parameters
        ----------
        search : object
            The discovery's search state.
        bases : Mapping[str, RoundBase]
            The round bases.
        rule : EvidenceRule
            The thresholds.
        n_tests : int
            Number of candidates of the round (the Bonferroni factor).
        used : set of str
            Names of the effects tried.

        Returns
        -------
        list of JointEvidence
            One per effect scored.
        """
        out = []
        for effect in self.candidates(used):
            located = self.locate(search, effect, bases) if effect.fitted else None
            if located is not None:
                tested = effect.at(located.grid_point, located.candidates)
                evidence = self._score(search, tested, bases, rule, n_tests)
                if evidence is not None:
                    evidence = dataclasses.replace(
                        evidence, effect=effect.at(located.point, located.candidates))
            elif not effect.fitted:
                evidence = self._score(search, effect, bases, rule, n_tests)
            else:
                evidence = None
            if evidence is not None:
                out.append(evidence)
        return out

    def locate(self, search, effect: VectorEffect, bases: Mapping) -> PointFit | None:
        """Where the data put the point of ``effect`` against the round's designs.

        The profile of the weighted, compensated joint fit over the force coefficients (the
        first pass of :meth:`_score`) over the candidate points, refined
        (:class:`~drake_uav.identification.discovery.fitted_point.PointProfile`).

        Parameters
        ----------
        search : object
            The discovery's search state.
        effect : VectorEffect
            A ``"towards_point"`` effect.
        bases : Mapping[str, RoundBase]
            The round bases.

        Returns
        -------
        PointFit or None
            The point; None when no force coefficient is fitted.
        """
        train = search.pool.variants.samples
        if effect not in self._profiles:
            self._profiles[effect] = (PointProfile(positions(train), train.time), {})
        profile, axes = self._profiles[effect]
        kernels = {}
        for k in (k for k in _FORCES if k in bases):
            base = bases[k]
            design = base.design
            variance = design.noise.variance
            if k not in axes:
                axes[k] = self._along_ned_axes(search, effect, k, variance)
            a, jac = axes[k]
            A, b, _, _ = base.blocks.total()
            kernels[k] = ProfileKernels.of(a, {s: j for s, j in jac.items() if s in variance},
                                           design.X, design.z, design.noise, A, b,
                                           len(design.z) / base.sse[0])
        if not kernels:
            return None
        return profile.against(kernels).locate()

    def _along_ned_axes(self, search, effect: VectorEffect, k: str,
                        variance: Mapping[str, float]
                        ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The change of coefficient ``k`` by a unit force along each NED axis (times the
        effect's logged magnitude), (N, 3), and its sensitivities to the noise sources."""
        params, magnitude = search.pool.params, effect.magnitude

        def along_axes(smp):
            view = smp.aligned(k)
            size = (np.asarray(view.signals[magnitude], dtype=float)[:, None]
                    if magnitude else 1.0)
            return {i: force_coefficient_change(view, params, k, size * ned_to_body(
                view, np.broadcast_to(np.eye(3)[i], (len(view), 3)))) for i in range(3)}
        columns, jac = columns_and_jacobians(along_axes, search.pool.variants, variance)
        return (np.column_stack([columns[i] for i in range(3)]),
                {s: np.column_stack([j[i] for i in range(3)]) for s, j in jac.items()})

    def _score(self, search, effect, bases, rule, n_tests) -> JointEvidence | None:
        """The joint evidence of ``effect`` against the round's designs
        (:func:`~drake_uav.identification.discovery.evidence.score_jointly`)."""
        columns = {k: CandidateColumns(*self._columns(search, effect, k)) for k in bases}
        return score_jointly(effect, effect.parameters, columns, bases, rule, n_tests,
                             effect.searched)

    # -- acceptance

    def accept(self, search, joint: Sequence[JointEvidence], named: Sequence, used: set[str],
               accept_named: Callable) -> FoundEffect | None:
        """The round's winner, or None.

        A passing vector effect that removes more held-out error than every passing
        per-coefficient effect (:attr:`JointEvidence.total`; a per-coefficient effect's summed
        over the coefficients it passed on) is tried first, then the per-coefficient effects
        (``accept_named(named, used)``), then the other passing vector effects. A force
        towards a located point, one choice among the grid's, goes first only when it removes
        :attr:`EvidenceRule.min_pse_reduction` more on each coefficient its total sums over,
        as a data-driven product must on its one coefficient; so does a force proportional to
        a logged channel, whose rival is the channel itself on each coefficient (which needs
        no direction). A force away from the centre of gravity whose twin at the centre of
        gravity passes too competes only when its moment removes
        :attr:`EvidenceRule.min_pse_reduction` more than the twin on each moment coefficient
        it moves (the twin is the same force with the lever arm fixed at zero: the simpler
        of two nested models, named unless the data ask for the moment). Every effect tried
        joins ``used``.

        Parameters
        ----------
        search : object
            The discovery's search state.
        joint : sequence of JointEvidence
            The vector effects' evidence of the round.
        named : sequence
            The per-coefficient candidates' evidence of the round.
        used : set of str
            Names of the effects tried (updated).
        accept_named : callable
            ``accept_named(named, used) -> FoundEffect or None``.

        Returns
        -------
        FoundEffect or None
            The effect accepted.
        """
        passing = [j for j in joint if j.passed]
        passing = sorted((j for j in passing if not _twin_at_cg_does_as_well(
            j, passing, search.rule.min_pse_reduction)), key=lambda j: -j.total)
        totals: dict[str, float] = {}
        for e in named:
            if e.passed and e.effect not in used:
                totals[e.effect] = totals.get(e.effect, 0.0) + e.pse_reduction
        best = max(totals.values(), default=-np.inf)

        def margin(j: JointEvidence) -> float:
            searched = j.effect.fitted or j.effect.magnitude
            return search.rule.min_pse_reduction * len(j.coefficients) if searched else 0.0

        for j in (j for j in passing if j.total - margin(j) > best):
            found = self._accept(search, j, used)
            if found is not None:
                return found
        found = accept_named(named, used)
        for j in passing:
            if found is not None:
                break
            if j.effect.name not in used:
                found = self._accept(search, j, used)
        return found

    def _accept(self, search, joint: JointEvidence, used: set[str]) -> FoundEffect | None:
        """The held-out decisions on ``joint`` coefficient by coefficient; its shape column
        added where kept."""
        effect = joint.effect
        used.add(effect.name)
        kept = []
        for k in joint.coefficients:
            current = (search.designs[k], search.tests[k])
            extended = (self._with_shape(search, joint, k, current[0]),
                        self._with_shape(search, joint, k, current[1], test=True))
            check = search.check(effect.name, k, current, extended, "round")
            search.checks.append(check)
            if check.kept:
                search.designs[k], search.tests[k] = extended
                kept.append(k)
        if not kept:
            return None
        self._accepted[effect.name] = effect
        return FoundEffect(effect.name, effect.explanation, "aerodynamic", tuple(kept),
                                tuple(self.evidence([joint], kept)), {})

    def _with_shape(self, search, joint: JointEvidence, k: str, design, test: bool = False):
        """``design`` with the effect's column on ``k`` at its joint estimate (one column
        ``<effect>:joint``, its scale refitted with the coefficient)."""
        columns, jac = self._columns(search, joint.effect, k, test)
        weights = {n: joint.estimate[joint.parameters.index(n)] for n in columns
                   if n in joint.parameters}

        def combine(values):
            return sum(w * values[n] for n, w in weights.items())

        return design.extended({"joint": combine(columns)},
                               {s: {"joint": combine(j)} for s, j in jac.items()},
                               prefix=f"{joint.effect.name}:")

    # -- parameters

    def with_parameters(self, search, found: Sequence[FoundEffect]) -> list[FoundEffect]:
        """``found`` with every vector effect's parameters from a joint refit.

        Against the final fits of the coefficients it is kept on (:meth:`parameters`).

        Parameters
        ----------
        search : object
            The discovery's search state.
        found : sequence of FoundEffect
            The findings.

        Returns
        -------
        list of FoundEffect
            The findings, vector effects with their joint parameters.
        """
        effects = {**{e.name: e for e in self.effects}, **self._accepted}
        path = None
        out = []
        for f in found:
            if f.name in effects:
                f = dataclasses.replace(f, parameters=self.parameters(
                    search, effects[f.name], f.coefficients))
                if effects[f.name].fitted:
                    path = positions(search.pool.variants.samples) if path is None else path
                    f = far_point_as_direction(f, path)
            out.append(f)
        return out

    def parameters(self, search, effect: VectorEffect, coefficients: Sequence[str]
                   ) -> dict[str, tuple[float, float]]:
        """Estimate and sigma of the effect's parameters, jointly over ``coefficients``.

        ``F`` the magnitude [N] (gain [N per unit] of a logged magnitude), ``Fr_x`` ... F times
        the application point [N m] where a moment coefficient carries it, and the
        application point ``r_x`` ... [m] (delta method) where F is estimated too. A point the
        data located: ``Fp_n, Fp_e, Fp_d``, F times its shift [N m] (the force linearised
        about it), and the point ``p_n, p_e, p_d`` [m, NED] (the located one moved by the
        shift: one Gauss-Newton step, its sigma by the delta method). The coefficients' own
        columns are refitted with them; the covariance is the sandwich of all the estimating
        equations (each coefficient's and the weighted shared ones) with the long-run
        covariance of their per-sample scores.

        Parameters
        ----------
        search : object
            The discovery's search state.
        effect : VectorEffect
            The effect.
        coefficients : sequence of str
            The coefficients it is kept on.

        Returns
        -------
        dict of str to (float, float)
            Parameter name -> (estimate, sigma).
        """
        if effect.fitted:
            effect = dataclasses.replace(effect, linearised=True)
        prefix = f"{effect.name}:"
        designs, names = {}, {}
        for k in coefficients:
            columns, jac = self._columns(search, effect, k)
            final = search.designs[k]
            residual = final.z - final.X @ final.solve()
            weight = effective_sample_size(residual) / float(residual @ residual)
            designs[k] = (final.without(prefix).extended(columns, jac), weight)
            names[k] = list(columns)
        parameters = tuple(n for n in effect.parameters if any(n in v for v in names.values()))
        q = len(parameters)
        blocks = []
        for k, (design, weight) in designs.items():
            A, b = design.moments()
            index = np.array([parameters.index(n) for n in names[k]])
            blocks.append(JointBlock(A, b, A.shape[0] - len(index), index, weight))
        phi, thetas, _ = joint_solve(blocks, q)
        offsets = np.cumsum([0] + [blk.p for blk in blocks])
        n_params = int(offsets[-1]) + q
        jacobian = np.zeros((n_params, n_params))
        scores = np.zeros((len(search.designs[coefficients[0]].z), n_params))
        shared = int(offsets[-1]) + np.arange(q)
        for (design, _), blk, theta, start in zip(designs.values(), blocks, thetas, offsets[:-1],
                                                  strict=True):
            own = start + np.arange(blk.p)
            phi_k = shared[blk.index]
            p = blk.p
            jacobian[np.ix_(own, own)] = blk.A[:p, :p]
            jacobian[np.ix_(own, phi_k)] = blk.A[:p, p:]
            jacobian[np.ix_(phi_k, own)] += blk.weight * blk.A[p:, :p]
            jacobian[np.ix_(phi_k, phi_k)] += blk.weight * blk.A[p:, p:]
            psi = design.scores(np.concatenate([theta, phi[blk.index]]))
            scores[:, own] = psi[:, :p]
            scores[:, phi_k] += blk.weight * psi[:, p:]
        scale = np.sqrt(np.maximum(np.abs(np.diag(jacobian)), 1e-300))
        inverse = np.linalg.pinv(jacobian / np.outer(scale, scale)) / np.outer(scale, scale)
        covariance = (inverse @ long_run_covariance(scores) @ inverse.T)[np.ix_(shared, shared)]
        out = {n: (float(phi[i]), float(np.sqrt(max(covariance[i, i], 0.0))))
               for i, n in enumerate(parameters)}
        if "F" in parameters:
            f = parameters.index("F")
            origins = {**dict.fromkeys(_ARMS, 0.0),
                       **dict(zip(_SHIFTS, effect.point or (0.0,) * 3, strict=True))}
            for i, n in enumerate(parameters):
                if n in origins:
                    gradient = np.zeros(q)
                    gradient[i], gradient[f] = 1.0 / phi[f], -phi[i] / phi[f] ** 2
                    label = f"r_{n[-1]}" if n in _ARMS else f"p_{n[-1]}"
                    out[label] = (float(origins[n] + phi[i] / phi[f]),
                                  float(np.sqrt(max(gradient @ covariance @ gradient, 0.0))))
        return out
