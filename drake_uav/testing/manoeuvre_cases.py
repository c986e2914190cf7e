"""Does the proposed manoeuvre resolve a near tie? One campaign flight, then the next one.

:func:`fly_next` flies a flight of the ``discovery`` campaign
(:mod:`~drake_uav.testing.discovery_cases`: the aerosonde, one effect put into the physics,
the three-axis multisine under the airspeed hold), runs the main job, and when the report
holds a near tie, designs the manoeuvre that separates it
(:func:`~drake_uav.diagrams.manoeuvre_design.propose_manoeuvre`) and flies it on the same
aircraft with the same effect (the physics do not change with the manoeuvre), then runs the
main job again. The tie is resolved when the second flight's findings are exactly the
injected effect and the report names no near tie of it; each pair of the injected effect
and a rival it was tied with is told apart (:func:`told_apart`) when the second flight
names the injected effect (or a near tie of it) and neither names the rival nor ties it
with the injected one.
"""

from __future__ import annotations

from drake_uav.diagrams import fly
from drake_uav.diagrams.manoeuvre_design import propose_manoeuvre
from drake_uav.identification.pipeline import identify
from drake_uav.testing.discovery_cases import (
    FLIGHT_DURATION,
    INJECTED,
    SUITES,
    calibrated_strength,
    measured_only,
)
from drake_uav.vehicles.loading import load_fixed_wing

__all__ = ["fly_next", "resolved", "tied_with", "told_apart", "PREDICTION_SEEDS"]

PREDICTION_SEEDS = 10_000
"""Offset of the seed of the design's predicted flight from the flights' seed."""


def resolved(run, expected: str) -> bool:
    """The job named exactly ``expected`` and no other effect comes close to it."""
    return list(run.findings) == [expected] and not any(
        t.winner.effect == expected for t in run.near_ties)


def tied_with(run, effect: str) -> set[str]:
    """The effects a run's near ties put in one group with ``effect`` (the accepted one and
    its rivals, in every tie that holds ``effect``), ``effect`` left out."""
    out = set()
    for tie in run.near_ties:
        members = {tie.winner.effect, *(a.effect for a in tie.alternatives)}
        if effect in members:
            out |= members
    return out - {effect}


def told_apart(run, expected: str, rival: str) -> bool:
    """The run ends the tie of ``expected`` and ``rival`` in favour of ``expected``.

    It names ``expected`` or ties it with what it names (a member of the same family may
    still be named for it: that is another pair's tie), and it neither names ``rival`` nor
    ties it with ``expected``."""
    group = tied_with(run, expected)
    return ((expected in run.findings or any(f in group for f in run.findings))
            and rival not in run.findings and rival not in group)


def fly_next(seed: int, effect: str, *, suite: str = "research", size: float = 0.2,
             turbulence: str = "light", duration: float = FLIGHT_DURATION,
             propulsion: str = "data") -> dict:
    """A campaign flight, its near ties, and the flight of the manoeuvre proposed for them.

    Parameters
    ----------
    seed : int
        Seed of both flights (turbulence and sensor noise).
    effect : str
        A key of :data:`~drake_uav.testing.discovery_cases.INJECTED`.
    suite, turbulence : str
        Sensor suite and turbulence level of both flights.
    size : float
        The effect's size on the campaign flight (its strength is kept on the next one).
    duration : float
        Length of both flights [s].
    propulsion : str
        The job's thrust on both flights: "data" (identified from the flight where the
        throttle moves on its own) or "catalog" (known, as from a logged motor speed or a
        declared propeller; the aircraft flown has the catalog's propulsion).

    Returns
    -------
    dict
        ``found_first`` and ``tied_first`` (findings and near-tie sentences of the campaign
        flight), ``expected``, ``selected`` (the inputs the design moves, empty without a
        tie), ``turn`` (the manoeuvre is flown in a turn), ``predicted`` (each pair's
        summary), ``found_next``, ``tied_next``, ``resolved`` (:func:`resolved` on the next
        flight; None without a tie) and ``pairs`` (each rival of the injected effect on
        the campaign flight -> :func:`told_apart` on the next flight; empty without a
        manoeuvre).

    Raises
    ------
    ValueError
        For an unknown effect or suite.
    """
    if effect not in INJECTED:
        raise ValueError(f"effect: {effect!r} unknown (known: {', '.join(INJECTED)})")
    if suite not in SUITES:
        raise ValueError(f"suite: {suite!r} unknown (known: {', '.join(SUITES)})")
    injection = INJECTED[effect]
    catalog = load_fixed_wing("aerosonde")
    strength = calibrated_strength(effect, size, turbulence, duration)
    options = {"aircraft": catalog, "turbulence": turbulence, "seed": seed,
               "duration": duration, "sensors": SUITES[suite](catalog.rho),
               **injection.fly_options(strength, catalog, duration)}
    first = identify(measured_only(fly(excitation="multisine", **options)), catalog, seed=seed,
                     propulsion=propulsion)
    out = {"expected": injection.expected, "found_first": ",".join(first.findings),
           "tied_first": " | ".join(t.sentence() for t in first.near_ties),
           "selected": "", "turn": False, "predicted": [], "found_next": "", "tied_next": "",
           "resolved": None, "pairs": {}}
    # The prediction's gusts are not the next flight's (its seed is another).
    design = propose_manoeuvre(first, duration=duration, propulsion=propulsion,
                               seed=PREDICTION_SEEDS + seed)
    if design is None:
        return out
    run = identify(measured_only(fly(excitation=design.signals, **options)), catalog,
                   seed=seed, propulsion=propulsion)
    rivals = tied_with(first, injection.expected)
    return out | {"selected": ",".join(design.selected), "turn": design.turn is not None,
                  "predicted": [s.summary() for s in design.separations],
                  "pairs": {r: told_apart(run, injection.expected, r) for r in sorted(rivals)},
                  "found_next": ",".join(run.findings),
                  "tied_next": " | ".join(t.sentence() for t in run.near_ties),
                  "resolved": resolved(run, injection.expected)}
