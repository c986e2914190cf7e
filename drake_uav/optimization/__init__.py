"""MathematicalProgram formulations and the analysis built on them.

* Fixed wing: :func:`trim` (level, climbing and turning trims), exact
  linear models and :func:`mode_analysis` (:mod:`~drake_uav.optimization.linearization`).
* Multirotor: :func:`minimum_snap` trajectories and segment-time allocation
  (:func:`optimize_segment_times`), and differential flatness from flat outputs
  to attitude, body rates, thrust and motor commands
  (:mod:`~drake_uav.optimization.flatness`); time-varying terminal sets along a
  reference (:func:`terminal_set`) and the tracking NMPC (:class:`TrackingNmpc`),
  Argyropoulos 2020, ch. 4.
* Motor failures: force closure (:func:`closure_holds`) and the largest
  torque-free thrust (:func:`max_thrust`, LP 5.22) of the healthy motors,
  Argyropoulos 2020, sec. 5.1; backward reachable tubes to near-hover attitude
  per failure set (:func:`recovery_tube`, sec. 5.2; solving needs the ``faults``
  extra, loading a cached tube does not).
"""

from drake_uav.optimization.allocation import (
    ClosureMismatchError,
    canonical_failed_motors,
    closure_holds,
    largest_angular_gap,
    max_thrust,
    max_thrust_allocation,
)
from drake_uav.optimization.flatness import (
    FlatAttitude,
    FlatReference,
    YawProfile,
    attitude_from_flat_outputs,
    flat_reference,
    reference_from_flat_outputs,
    velocity_heading,
)
from drake_uav.optimization.linearization import (
    EULER_STATE_NAMES,
    LinearModel,
    Mode,
    ModeAnalysis,
    decoupled_models,
    linearize_euler,
    mode_analysis,
)
from drake_uav.optimization.min_snap import (
    MinimumSnap,
    PolynomialTrajectory,
    TimeAllocationResult,
    TrajectoryInfeasibleError,
    minimum_snap,
    optimize_segment_times,
)
from drake_uav.optimization.nmpc import NmpcResult, NmpcSettings, TrackingNmpc
from drake_uav.optimization.reachability import RecoveryTube, TubeSettings, recovery_tube
from drake_uav.optimization.terminal_set import ReferenceTable, TerminalSet, terminal_set
from drake_uav.optimization.trim import TrimError, TrimResult, trim

__all__ = [
    "ClosureMismatchError",
    "EULER_STATE_NAMES",
    "FlatAttitude",
    "FlatReference",
    "LinearModel",
    "MinimumSnap",
    "NmpcResult",
    "NmpcSettings",
    "RecoveryTube",
    "ReferenceTable",
    "TerminalSet",
    "TrackingNmpc",
    "Mode",
    "ModeAnalysis",
    "PolynomialTrajectory",
    "TimeAllocationResult",
    "TrajectoryInfeasibleError",
    "TubeSettings",
    "TrimError",
    "TrimResult",
    "YawProfile",
    "attitude_from_flat_outputs",
    "canonical_failed_motors",
    "closure_holds",
    "decoupled_models",
    "flat_reference",
    "largest_angular_gap",
    "linearize_euler",
    "max_thrust",
    "max_thrust_allocation",
    "minimum_snap",
    "mode_analysis",
    "optimize_segment_times",
    "recovery_tube",
    "reference_from_flat_outputs",
    "terminal_set",
    "trim",
    "velocity_heading",
]
