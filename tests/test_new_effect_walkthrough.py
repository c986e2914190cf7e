"""The contributor's walk-through of docs/architecture.md: a new effect in a few lines.

An effect is a name, one line of physics, the coefficients it may enter and a function
returning its regressor columns; the discovery loop scores it with every other candidate
(:func:`~drake_uav.identification.discovery.evidence.score`) and names it where the data
hold it.
"""

from synthetic_flight import synthetic_samples

from drake_uav.identification.discovery.effects import Effect
from drake_uav.identification.discovery.loop import discover


def lift_break(samples, params, coefficient):
    """The lift's fall past the linear range, as the cube of the angle of attack."""
    return {"alpha3": samples.condition.alpha ** 3}


LIFT_BREAK = Effect("lift_break", "the lift falls off with the cube of alpha past the "
                    "linear range", ("CL",), lift_break)


def test_a_new_effect_is_named_where_the_flight_holds_it():
    params, samples, _ = synthetic_samples(
        increment=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0), seed=2, duration=40.0)
    result = discover(samples, params, effects=[LIFT_BREAK], vector_effects=[],
                      fallback=False)
    assert [(f.name, f.coefficients) for f in result.found] == [("lift_break", ("CL",))]


def test_a_new_effect_is_not_named_on_a_flight_without_it():
    params, samples, _ = synthetic_samples(seed=1, duration=40.0)
    result = discover(samples, params, effects=[LIFT_BREAK], vector_effects=[],
                      fallback=False)
    assert result.found == ()
