"""Identification benchmark: batch and recursive estimator speed, and VFF against CFF.

Run: python benchmarks/bench_identification.py [--quick]

Prints
* batch OLS / GTLS / PCA-TLS on 150,000 samples x 7 regressors (target <= 0.5 s);
* recursive update cost per sample for RLS and recursive TLS, CFF and VFF (target <= 50 us);
* the RecursiveIdentifier in a small diagram at 100 Hz (simulated / wall-clock time);
* the RecursiveIdentifier inside the identification flight (plant, Dryden, sensors), fed
  by AeroRegressors: real-time factor with one and with six identifiers (target >= 50x);
* Vaiopoulos 2017, sec. 4.3.9: a C_m model whose parameters change at t = 300 s (100 Hz, 600 s):
  re-convergence time and steady-state variance of the VFF estimator and of CFF estimators,
  and the best CFF of equal (or lower) steady-state variance.

Each speed figure is also printed as a FIGURE line (benchmarks/figures.py); ``--quick`` runs
every part on a tenth of the samples, the in-flight real-time factors on a 30 s flight flown
once. Flight real-time factors are
simulated time over CPU time of this process.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from figures import figure
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.diagrams.identification_flight import build_identification_flight
from drake_uav.identification.statistics.recursive import (
    RecursiveOLS,
    RecursiveTLS,
    VariableForgetting,
    reconvergence_time,
)
from drake_uav.identification.statistics.regression import (
    InsufficientExcitationWarning,
    ols,
    pca_tls,
    tls,
)
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.systems.identifiers import (
    AeroRegressors,
    RecursiveIdentifier,
    RecursiveIdentifierParams,
)
from drake_uav.vehicles.fixed_wing import aerosonde

BATCH_TARGET = 0.5  # s for 150,000 x 7
RECURSIVE_TARGET = 50e-6  # s per sample
IN_FLIGHT_TARGET = 50.0  # real-time factor of the flight with the identifier inside


def filtered_noise(n, m, tau_samples, rng):
    """m columns of unit-variance first-order filtered white noise."""
    a = np.exp(-1.0 / tau_samples)
    shocks = rng.standard_normal((n, m)) * np.sqrt(1 - a * a)
    out = np.empty((n, m))
    out[0] = rng.standard_normal(m)
    for i in range(1, n):
        out[i] = a * out[i - 1] + shocks[i]
    return out


def regression_data(n, rng, unexcited_last=False):
    """[1, six regressors] with 20 % regressor noise, z with SNR 20; returns X, z, error_std."""
    signal = 0.05 * filtered_noise(n, 6, 30.0, rng)
    if unexcited_last:
        signal[:, -1] = 0.0
    X0 = np.column_stack([np.ones(n), signal])
    theta = np.array([0.02, -0.4, -1.0, 0.2, 0.3, -0.1, 0.05])
    y = X0 @ theta
    error_std = np.append(np.append(0.0, np.full(6, 0.01)), y.std() / 20.0)
    X = X0 + error_std[:7] * rng.standard_normal(X0.shape)
    return X, y + error_std[7] * rng.standard_normal(n), error_std


def best_of(fn, repeats=5):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times))


def bench_batch(samples=150_000):
    rng = np.random.default_rng(0)
    X, z, c = regression_data(samples, rng)
    Xu, zu, cu = regression_data(samples, rng, unexcited_last=True)
    print(f"Batch, {samples:,} samples x 7 regressors (target 0.5 s for 150,000): "
          "median / min of 5")
    cases = [
        ("OLS", lambda: ols(X, z)),
        ("GTLS", lambda: tls(X, z, c)),
        ("PCA-TLS, all excited", lambda: pca_tls(X, z, c)),
        ("PCA-TLS, one input not excited", lambda: pca_tls(Xu, zu, cu)),
    ]
    for name, fn in cases:
        median, fastest = best_of(fn)
        print(
            f"  {name:32s} {median * 1e3:7.1f} ms / {fastest * 1e3:6.1f} ms"
            f"   ratio to target {median * 150_000 / samples / BATCH_TARGET:.3f}"
        )
        figure(f"batch_ms_{_key(name)}", fastest * 1e3, "ms", "lower")
    print(f"  PCA-TLS rank with the idle input: {pca_tls(Xu, zu, cu).rank} of 7")


def per_sample(est, X, z):
    zl = [float(v) for v in z]
    t0 = time.process_time()
    for i in range(len(zl)):
        est.update(X[i], zl[i])
    return (time.process_time() - t0) / len(zl)


def bench_recursive(samples=20_000):
    rng = np.random.default_rng(1)
    X, z, c = regression_data(samples, rng)
    Xu, zu, cu = regression_data(samples, rng, unexcited_last=True)
    c = np.where(c > 0, c, 1e-6)
    cu = np.where(cu > 0, cu, 1e-6)
    print("\nRecursive update, 7 parameters (target 50 us per sample)")
    cases = [
        ("RLS, CFF 0.999", RecursiveOLS(7, 0.999), X, z),
        ("RLS, VFF", RecursiveOLS(7, VariableForgetting()), X, z),
        ("recursive GTLS, CFF 0.999", RecursiveTLS(7, c, forgetting=0.999), X, z),
        ("recursive GTLS, VFF", RecursiveTLS(7, c, forgetting=VariableForgetting()), X, z),
        ("recursive PCA-TLS, idle input", RecursiveTLS(7, cu), Xu, zu),
    ]
    for name, est, Xc, zc in cases:
        cost = min(per_sample(est, Xc, zc) for _ in range(2))
        extra = f"  (rank {est.rank})" if isinstance(est, RecursiveTLS) else ""
        print(
            f"  {name:32s} {cost * 1e6:6.1f} us   ratio to target "
            f"{cost / RECURSIVE_TARGET:.2f}{extra}"
        )
        figure(f"recursive_us_{_key(name)}", cost * 1e6, "us", "lower")


def bench_system(n=3000):
    rng = np.random.default_rng(2)
    period = 0.01
    X, z, c = regression_data(n, rng)
    c = np.where(c > 0, c, 1e-6)
    print(f"\nRecursiveIdentifier in a diagram, 100 Hz updates, {n * period:g} s")
    for method in ("tls", "ols"):
        builder = DiagramBuilder()
        breaks = (np.arange(n + 1) - 0.5) * period
        xs = builder.AddSystem(
            TrajectorySource(PiecewisePolynomial.ZeroOrderHold(breaks, np.vstack([X, X[-1]]).T))
        )
        zs = builder.AddSystem(
            TrajectorySource(PiecewisePolynomial.ZeroOrderHold(breaks, np.append(z, z[-1])[None]))
        )
        params = RecursiveIdentifierParams(
            names=tuple(f"theta{i}" for i in range(7)),
            error_std=tuple(c),
            method=method,
            variable_forgetting=VariableForgetting(),
            period=period,
        )
        ident = builder.AddSystem(RecursiveIdentifier(params))
        builder.Connect(xs.get_output_port(), ident.GetInputPort("regressors"))
        builder.Connect(zs.get_output_port(), ident.GetInputPort("observation"))
        simulator = Simulator(builder.Build())
        t0 = time.process_time()
        simulator.AdvanceTo((n - 0.5) * period)
        wall = time.process_time() - t0
        sim_time = (n - 0.5) * period
        print(
            f"  method {method}: {sim_time / wall:6.0f}x real time, "
            f"{wall / n * 1e6:5.1f} us per update including sources"
        )
        figure(f"identifier_diagram_rtf_{method}", sim_time / wall, "x")


def _identifiers(coefficients):
    """``extend`` hook: one AeroRegressors + RecursiveIdentifier (VFF TLS) per coefficient."""
    params = aerosonde()

    def extend(builder, ports):
        for coefficient in coefficients:
            regressors = builder.AddSystem(AeroRegressors(params, coefficient))
            for name in ("air_data", "state", "aero_coefficients"):
                builder.Connect(ports[name], regressors.GetInputPort(name))
            builder.Connect(ports["surfaces"], regressors.GetInputPort("controls"))
            identifier = builder.AddSystem(RecursiveIdentifier(RecursiveIdentifierParams(
                names=regressors.names, error_std=(1e-4,) * (len(regressors.names) + 1),
                variable_forgetting=VariableForgetting())))
            builder.Connect(regressors.GetOutputPort("regressors"),
                            identifier.GetInputPort("regressors"))
            builder.Connect(regressors.GetOutputPort("observation"),
                            identifier.GetInputPort("observation"))

    return extend


def bench_in_flight(duration=120.0, repeats=2):
    print(f"\nRecursiveIdentifier inside the identification flight ({duration:.0f} s, light "
          f"turbulence, 100 Hz), best of {repeats}:")
    rtf = {}
    for label, coefficients in (("flight alone", ()), ("with a C_m identifier", ("Cm",)),
                                ("with six identifiers", COEFFICIENTS)):
        flight = build_identification_flight(
            "aerosonde", "light", duration=duration,
            extend=_identifiers(coefficients) if coefficients else None)
        cpu = []
        for _ in range(repeats):
            start = time.process_time()
            flight.simulate()
            cpu.append(time.process_time() - start)
        rtf[label] = duration / min(cpu)
        print(f"  {label:24s} {rtf[label]:6.1f}x real time")
    one = rtf["with a C_m identifier"]
    added_us = 1e6 / 100 * (1 / one - 1 / rtf["flight alone"])
    print(f"  one identifier costs {added_us:.0f} us "
          f"per 10 ms tick; target >= {IN_FLIGHT_TARGET:.0f}x: "
          f"{'met' if one >= IN_FLIGHT_TARGET else 'missed'}")
    figure("flight_light_rtf", rtf["flight alone"], "x")
    figure("flight_identifier_rtf", one, "x")
    figure("flight_six_identifiers_rtf", rtf["with six identifiers"], "x")
    figure("identifier_tick_us", added_us, "us", "lower")


def bench_forgetting():
    rate, duration, t_change = 100.0, 600.0, 300.0
    n = int(rate * duration)
    t = np.arange(n) / rate
    rng = np.random.default_rng(3)
    w = filtered_noise(n, 3, 0.3 * rate, rng) * np.array([0.03, 0.01, 0.03])
    X = np.column_stack([np.ones(n), 0.05 + w[:, 0], w[:, 1], w[:, 2]])
    before = np.array([0.02, -0.38, -3.6, -0.5])
    after = np.array([0.03, -0.60, -3.6, -0.35])
    truth = np.where((t >= t_change)[:, None], after, before)
    z = np.sum(X * truth, axis=1) + (np.std(X @ before) / 20.0) * rng.standard_normal(n)
    band = 0.1 * np.abs(after - before)
    band[band == 0] = 0.1 * np.abs(before[band == 0])
    steady = (t >= t_change - 100.0) & (t < t_change)

    def figures(forgetting):
        est = RecursiveOLS(4, forgetting).run(X, z).estimate
        err2 = np.mean((est[steady] - truth[steady]) ** 2, axis=0) / band**2
        return reconvergence_time(t, est, truth, t_change, band), float(np.mean(err2))

    print(
        "\nForgetting (Vaiopoulos 2017 4.3.9): C_m parameters change at t = 300 s, 100 Hz, SNR 20;"
        "\n  re-convergence = time until every parameter stays within 10 % of its step,"
        "\n  variance = mean squared error / band^2 over the 100 s before the change"
    )
    vff_time, vff_var = figures(VariableForgetting())
    print(
        f"  VFF (lambda_max = 1)        re-convergence {vff_time:7.2f} s   variance {vff_var:.4f}"
    )
    cff = {}
    for lam in (0.99, 0.995, 0.997, 0.998, 0.999, 0.9995, 0.9997, 0.9999, 1.0):
        cff[lam] = figures(lam)
        print(
            f"  CFF lambda = {lam:<8}       re-convergence {cff[lam][0]:7.2f} s   "
            f"variance {cff[lam][1]:.4f}"
        )
    quiet = [lam for lam in cff if cff[lam][1] <= vff_var]
    pool = quiet or [min(cff, key=lambda lam: cff[lam][1])]
    best = min(pool, key=lambda lam: cff[lam][0])
    print(
        f"  best CFF with variance <= VFF's: lambda {best}, re-convergence {cff[best][0]:.2f} s"
        f" vs VFF {vff_time:.2f} s"
    )
    noisier = [lam for lam in cff if cff[lam][1] > vff_var]
    if noisier:
        near = min(noisier, key=lambda lam: cff[lam][1])
        print(
            f"  nearest noisier CFF: lambda {near}, variance x{cff[near][1] / vff_var:.1f}, "
            f"re-convergence {cff[near][0]:.2f} s"
        )


def _key(label: str) -> str:
    """FIGURE name part of a printed label: lower case, words joined by '_'."""
    return "_".join("".join(c if c.isalnum() else " " for c in label.lower()).split())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="a tenth of the samples, a 30 s flight flown once")
    quick = parser.parse_args().quick
    warnings.simplefilter("ignore", InsufficientExcitationWarning)
    bench_batch(15_000 if quick else 150_000)
    bench_recursive(2_000 if quick else 20_000)
    bench_system(300 if quick else 3000)
    bench_in_flight(*((30.0, 1) if quick else (120.0, 2)))
    bench_forgetting()


if __name__ == "__main__":
    main()
