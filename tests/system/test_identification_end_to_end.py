"""End to end: simulated Aerosonde identification flights -> the library's pipeline -> the
aircraft's force and moment derivatives within their reported uncertainty of the truth.

Three 120 s flights (seeds 1, 2, 3: the first three, not picked), light turbulence, the
default multisine on elevator, aileron and rudder, the default sensor suite (Vaiopoulos 2017
Table 7). ``identify_derivatives(log, aerosonde())`` isolates the six coefficients from the
measured specific force, rates and air data and fits each on the aircraft's own terms
(31 derivatives), bias-compensated for the sensor noise, with sigma from the long-run
covariance of the fit's scores and the joint covariance of all 31.

Statistics. With honest sigmas each normalised error ``z = (estimate - truth) / sigma`` is
about N(0, 1): one term lies outside 2 sigma 4.6 % of the time. A flight has about 21
significant terms, the three flights about 63, so requiring every one of them inside
2 sigma would fail a correct pipeline most of the time (0.954^63 = 5 % pass rate for
independent terms; it held on 9 of 19 calibration flights one by one) and could only pass
reliably with inflated sigmas. The acceptance "within 2 sigma for all significant terms"
is therefore tested as:

1. family-wise 2 sigma: every significant term of the three flights within the two-sided
   Bonferroni bound that keeps the family-wise error at the 4.6 % of one 2-sigma test
   (about 3.3 sigma for 63 terms): a biased derivative fails here;
2. calibration: the sum of z^2 over all 93 terms within the 95 % interval of its
   distribution under the reported joint covariance (a weighted sum of chi-square(1),
   Satterthwaite's scaled chi-square with mean tr R and variance 2 tr R^2 per flight; the
   fits are strongly correlated, e.g. C_l and C_n share the sideslip vane): understated
   sigmas (the white-residual formula gave half the true spread) or overstated ones fail;
3. not vacuous: the derivatives the flight must determine are significant in every
   flight, and the primary stability, damping and control derivatives have a relative
   sigma below 10 %.

The fraction of terms within 2 sigma and the per-flight outcome of the literal criterion
are printed (``-s``), with the per-term table of the first flight.
"""

import math

import numpy as np
import pytest
from scipy import stats

from drake_uav.diagrams import fly
from drake_uav.identification.pipeline import identify_derivatives
from drake_uav.vehicles import aerosonde

PARAMS = aerosonde()
SEEDS = (1, 2, 3)
DURATION = 120.0
TWO_SIGMA = 2.0 * stats.norm.sf(2.0)  # 4.55 %: the false-alarm rate of one 2-sigma test

# Non-zero derivatives a 120 s multisine flight at one trim point must determine. Left
# out: the drag polar's curvature (CD_alpha, CD_alpha2: +-2 deg of alpha do not separate
# it from CD_0, sigma ~1.6 x the value) and the small cross derivative Cn_p (0.022, sigma
# ~30 % of it).
REQUIRED = tuple(n for n, v in PARAMS.derivatives.items()
                 if v != 0.0 and n not in ("CD_alpha", "CD_alpha2", "Cn_p"))
# Static stability, damping and control power: relative sigma below 10 %.
PRIMARY = ("CL_alpha", "CY_beta", "Cl_beta", "Cl_p", "Cl_aileron", "Cm_alpha", "Cm_q",
           "Cm_elevator", "Cn_beta", "Cn_r")
PRIMARY_RELATIVE_SIGMA = 0.10


@pytest.fixture(scope="module")
def flights():
    """Per seed: (derivatives, truth, z, significant) in the fits' name order."""
    out = {}
    for seed in SEEDS:
        log = fly(PARAMS, turbulence="light", seed=seed, duration=DURATION)
        fit = identify_derivatives(log, PARAMS)
        truth = np.array([PARAMS.derivative(n) for n in fit.names])
        z = (fit.estimate - truth) / fit.sigma
        significant = np.concatenate([fit[k].significant for k in fit.fits])
        out[seed] = (fit, truth, z, significant)
    _print_summary(out)
    return out


def _print_summary(flights):
    fit, truth, z, significant = flights[SEEDS[0]]
    print(f"\nseed {SEEDS[0]}: {'term':>12} {'estimate':>10} {'sigma':>9} {'truth':>9} "
          f"{'z':>6} significant")
    for i, name in enumerate(fit.names):
        print(f"{'':8}{name:>12} {fit.estimate[i]:10.5f} {fit.sigma[i]:9.5f} {truth[i]:9.5f} "
              f"{z[i]:6.2f} {'yes' if significant[i] else 'no'}")
    all_z = np.concatenate([f[2] for f in flights.values()])
    sig_z = np.concatenate([f[2][f[3]] for f in flights.values()])
    print(f"all terms within 2 sigma: {np.mean(np.abs(all_z) <= 2):.3f} of {all_z.size}; "
          f"significant: {np.mean(np.abs(sig_z) <= 2):.3f} of {sig_z.size}; "
          f"rms z {np.sqrt(np.mean(all_z**2)):.2f}")
    for seed, (_, _, z, significant) in flights.items():
        print(f"seed {seed}: {significant.sum()} significant, max |z| "
              f"{np.abs(z[significant]).max():.2f}, all within 2 sigma: "
              f"{bool(np.all(np.abs(z[significant]) <= 2))}")


def test_every_significant_derivative_is_within_its_family_wise_two_sigma(flights):
    tested = sum(int(f[3].sum()) for f in flights.values())
    bound = stats.norm.isf(TWO_SIGMA / (2 * tested))
    assert 3.0 < bound < 3.6
    outside = [(seed, name, round(float(z[i]), 2))
               for seed, (fit, _, z, significant) in flights.items()
               for i, name in enumerate(fit.names) if significant[i] and abs(z[i]) > bound]
    assert not outside, (bound, outside)


def test_normalised_errors_have_unit_spread(flights):
    total, mean, variance = 0.0, 0.0, 0.0
    for fit, _, z, _ in flights.values():
        correlation = fit.covariance / np.outer(fit.sigma, fit.sigma)
        total += float(z @ z)
        mean += float(np.trace(correlation))
        variance += 2.0 * float(np.sum(correlation**2))
    dof = 2.0 * mean**2 / variance
    scale = mean / dof
    low, high = scale * stats.chi2.ppf([0.025, 0.975], dof)
    print(f"sum z^2 = {total:.1f}, 95 % interval [{low:.1f}, {high:.1f}] "
          f"(mean {mean:.0f}, {dof:.1f} equivalent degrees of freedom)")
    assert low <= total <= high, (total, low, high)
    # The interval must be able to see a twofold error of sigma either way.
    assert high < 4.0 * mean and low > mean / 4.0


def test_the_flight_determines_the_derivatives_it_must(flights):
    for seed, (fit, truth, _, significant) in flights.items():
        names = list(fit.names)
        missed = [n for n in REQUIRED if not significant[names.index(n)]]
        assert not missed, (seed, missed)
        relative = {n: fit.sigma[names.index(n)] / abs(truth[names.index(n)]) for n in PRIMARY}
        loose = {n: round(float(r), 3) for n, r in relative.items()
                 if not r < PRIMARY_RELATIVE_SIGMA}
        assert not loose, (seed, loose)
        assert all(math.isfinite(s) and s > 0 for s in fit.sigma)
