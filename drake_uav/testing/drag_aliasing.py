"""How much of each drag-axis effect of the campaign a flight can tell apart.

A term the baseline can already represent is not missing from the model: its fit moves the
baseline's coefficients instead, and no evidence rule can name it. For each effect of
:data:`~drake_uav.testing.discovery_cases.INJECTED` that acts on C_D, along a flight's
truth, :func:`drag_axis_shares` gives its *unique share*: ``1 - R^2`` of its term regressed
on a set of columns, the part of its variation over the flight that the set cannot
reproduce (1: nothing of it; 0: all of it). The sets are the catalog's C_D terms, those
with the throttle terms of an identified thrust
(:func:`~drake_uav.identification.propulsion.thrust_drag_columns`: what the job fits when
the flight determines the thrust), and the catalog's terms with each other drag-axis
effect (whether two effects differ when the thrust is known).

``benchmarks/bench_drag_aliasing.py`` prints them for the campaign's flights; docs/main_job.md
("How often it finds what is there") reads them.
"""

from __future__ import annotations

import numpy as np

from drake_uav.identification.discovery.coefficient_design import baseline_names
from drake_uav.identification.propulsion import thrust_drag_columns
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.coefficients import regressor_matrix
from drake_uav.testing.discovery_cases import INJECTED, aero_condition, qbar_s
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["DRAG_AXIS", "CATALOG", "WITH_THRUST", "unique_share", "drag_axis_shares"]

DRAG_AXIS = ("propwash_drag", "tow_force", "drag_drift", "logged_tension")
"""The campaign's effects whose term is on C_D (the tow below the centre of gravity has the
tow's C_D term)."""
CATALOG = "catalog C_D terms"
WITH_THRUST = "catalog C_D terms + identified thrust"


def unique_share(term: np.ndarray, columns: list[np.ndarray]) -> float:
    """``1 - R^2`` of ``term`` regressed on ``columns`` by least squares [-]."""
    X = np.column_stack(columns)
    theta = np.linalg.lstsq(X, term, rcond=None)[0]
    return float(np.var(term - X @ theta) / np.var(term))


def drag_axis_shares(flight: FlightLog, params: FixedWingParams) -> dict[str, dict[str, float]]:
    """effect -> set of columns -> the effect's unique share against it, along ``flight``'s
    truth (a flight of :func:`~drake_uav.diagrams.fly`)."""
    condition = aero_condition(flight, params)
    catalog = list(regressor_matrix(baseline_names(params, "CD"), condition, params.b,
                                    params.c).T)
    thrust = list(thrust_drag_columns(condition.alpha, condition.airspeed, flight["throttle"],
                                      qbar_s(condition.airspeed, params)).values())
    terms = {key: np.broadcast_to(INJECTED[key].term(condition, flight, params),
                                  flight.time.shape) for key in DRAG_AXIS}
    out = {}
    for key, term in terms.items():
        out[key] = {CATALOG: unique_share(term, catalog),
                    WITH_THRUST: unique_share(term, catalog + thrust)}
        out[key] |= {f"{CATALOG} + {other}": unique_share(term, catalog + [column])
                     for other, column in terms.items() if other != key}
    return out
