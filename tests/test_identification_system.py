"""RecursiveIdentifier LeafSystem: ports, equivalence with the estimators, reproducibility."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.identification.statistics.recursive import VariableForgetting
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.optimization.trim import trim
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.systems.identifiers import (
    AeroRegressors,
    RecursiveIdentifier,
    RecursiveIdentifierParams,
)
from drake_uav.vehicles.fixed_wing import aerosonde

PERIOD = 0.01  # s
NAMES = ("C_m0", "C_malpha", "C_mqn", "C_mde")
THETA = np.array([0.02, -0.38, -3.6, -0.5])
ERROR_STD = (1e-6, 0.0015, 0.0005, 0.0015, 0.002)


def samples(n, seed, elevator=True):
    """Measured regressors (n, 4) and observations (n,) of a pitch model with sensor noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * PERIOD
    alpha = 0.05 + 0.03 * np.sin(2.1 * t) + 0.01 * np.sin(5.3 * t + 1.0)
    qn = 0.01 * np.sin(3.7 * t + 0.5)
    de = 0.03 * np.sin(1.3 * t) + 0.01 * np.sin(7.1 * t) if elevator else np.zeros(n)
    X = np.column_stack([np.ones(n), alpha, qn, de])
    z = X @ THETA + ERROR_STD[-1] * rng.standard_normal(n)
    Xm = X + np.asarray(ERROR_STD[:4]) * rng.standard_normal(X.shape)
    return Xm, z


def build(params, X, z):
    """Diagram: zero-order-hold sources of X and z feeding the identifier."""
    n = len(z)
    breaks = (np.arange(n + 1) - 0.5) * PERIOD  # sample k is held around t = k * PERIOD
    builder = DiagramBuilder()
    xs = builder.AddSystem(
        TrajectorySource(PiecewisePolynomial.ZeroOrderHold(breaks, np.vstack([X, X[-1]]).T))
    )
    zs = builder.AddSystem(
        TrajectorySource(PiecewisePolynomial.ZeroOrderHold(breaks, np.append(z, z[-1])[None]))
    )
    ident = builder.AddSystem(RecursiveIdentifier(params))
    builder.Connect(xs.get_output_port(), ident.GetInputPort("regressors"))
    builder.Connect(zs.get_output_port(), ident.GetInputPort("observation"))
    return builder.Build(), ident


def simulate(params, X, z):
    diagram, ident = build(params, X, z)
    simulator = Simulator(diagram)
    simulator.AdvanceTo((len(z) - 0.5) * PERIOD)  # updates at k * PERIOD, k < len(z)
    return ident, ident.GetMyContextFromRoot(simulator.get_context())


def test_ports_sizes_and_no_direct_feedthrough():
    ident = RecursiveIdentifier(RecursiveIdentifierParams(names=NAMES, error_std=ERROR_STD))
    assert ident.GetInputPort("regressors").size() == 4
    assert ident.GetInputPort("observation").size() == 1
    for name, size in (("estimate", 4), ("sigma", 4), ("excitation", 4), ("forgetting", 1)):
        assert ident.GetOutputPort(name).size() == size
    for i in range(ident.num_input_ports()):
        for j in range(ident.num_output_ports()):
            assert not ident.HasDirectFeedthrough(i, j)
    assert ident.names == NAMES


@pytest.mark.parametrize(
    "method, forgetting",
    [("tls", VariableForgetting()), ("tls", 0.999), ("ols", VariableForgetting()), ("ols", 1.0)],
)
def test_diagram_equals_the_offline_estimator(method, forgetting):
    X, z = samples(800, seed=1)
    vff = forgetting if isinstance(forgetting, VariableForgetting) else None
    cff = 1.0 if vff else forgetting
    params = RecursiveIdentifierParams(
        names=NAMES,
        error_std=ERROR_STD,
        method=method,
        forgetting=cff,
        variable_forgetting=vff,
        period=PERIOD,
    )
    ident, context = simulate(params, X, z)
    offline = params.make_estimator()
    offline.run(X, z)
    np.testing.assert_array_equal(context.get_discrete_state_vector().CopyToVector(), offline.state)
    estimate = ident.GetOutputPort("estimate").Eval(context)
    np.testing.assert_array_equal(estimate, offline.estimate)
    np.testing.assert_allclose(ident.GetOutputPort("sigma").Eval(context), offline.sigma())
    assert ident.GetOutputPort("forgetting").Eval(context)[0] == offline.forgetting_factor
    # the identified model is right: within 3 sigma of the truth, all parameters excited
    sigma = ident.GetOutputPort("sigma").Eval(context)
    assert np.all(np.abs(estimate - THETA) < 3 * sigma)
    np.testing.assert_array_equal(ident.GetOutputPort("excitation").Eval(context), 1.0)


def test_unexcited_parameter_is_flagged():
    X, z = samples(800, seed=2, elevator=False)
    params = RecursiveIdentifierParams(names=NAMES, error_std=ERROR_STD, period=PERIOD)
    ident, context = simulate(params, X, z)
    np.testing.assert_array_equal(ident.GetOutputPort("excitation").Eval(context), [1, 1, 1, 0])
    sigma = ident.GetOutputPort("sigma").Eval(context)
    assert np.isinf(sigma[3]) and np.all(np.isfinite(sigma[:3]))
    assert np.all(np.isfinite(ident.GetOutputPort("estimate").Eval(context)))


def test_results_depend_only_on_the_context():
    X, z = samples(400, seed=3)
    params = RecursiveIdentifierParams(
        names=NAMES, error_std=ERROR_STD, variable_forgetting=VariableForgetting(), period=PERIOD
    )
    diagram, ident = build(params, X, z)
    first = Simulator(diagram)
    first.AdvanceTo(2.0)
    saved = first.get_context().Clone()
    first.AdvanceTo(3.995)
    second = Simulator(diagram, saved)  # restart from the saved context
    second.AdvanceTo(3.995)
    a = ident.GetMyContextFromRoot(first.get_context()).get_discrete_state_vector()
    b = ident.GetMyContextFromRoot(second.get_context()).get_discrete_state_vector()
    np.testing.assert_array_equal(a.CopyToVector(), b.CopyToVector())


def test_prior_start():
    cov0 = np.diag([1e-6, 1e-4, 1e-2, 1e-4])
    params = RecursiveIdentifierParams(
        names=NAMES,
        error_std=ERROR_STD,
        theta0=tuple(THETA),
        covariance0=tuple(map(tuple, cov0)),
    )
    ident = RecursiveIdentifier(params)
    context = ident.CreateDefaultContext()
    np.testing.assert_allclose(ident.GetOutputPort("estimate").Eval(context), THETA)
    np.testing.assert_allclose(ident.GetOutputPort("sigma").Eval(context), np.sqrt(np.diag(cov0)))


@pytest.mark.parametrize(
    "change, field",
    [
        ({"names": ("a", "a", "b", "c")}, "names"),
        ({"error_std": (1.0, 1.0)}, "error_std"),
        ({"error_std": (0.0, 1.0, 1.0, 1.0, 1.0)}, "error_std"),
        ({"method": "kalman"}, "method"),
        ({"forgetting": 0.0}, "forgetting"),
        ({"snr_min": -1.0}, "snr_min"),
        ({"period": 0.0}, "period"),
        ({"theta0": (1.0,)}, "theta0"),
        ({"covariance0": ((1.0,),)}, "covariance0"),
        ({"variable_forgetting": VariableForgetting(gamma=5.0)}, "gamma"),
    ],
)
def test_invalid_parameters_name_the_field(change, field):
    kwargs = {"names": NAMES, "error_std": ERROR_STD, **change}
    with pytest.raises(ValueError, match=field):
        RecursiveIdentifierParams(**kwargs).validate()


def test_aero_regressors_reproduce_the_plant_coefficients():
    """Regressor row times the true derivatives is the plant's coefficient, for all six
    (off trim: rates, sideslip, wind, saturated throttle)."""
    params = aerosonde()
    plant = FixedWingPlant(params)
    state = trim(params, 25.0).state.copy()
    state[8:13] += [1.5, -0.8, 0.3, -0.2, 0.25]
    controls = np.array([-0.1, 0.05, -0.03, 1.3])
    builder = DiagramBuilder()
    builder.AddSystem(plant)
    systems = {c: builder.AddSystem(AeroRegressors(params, c)) for c in COEFFICIENTS}
    for regressors in systems.values():
        for name in ("air_data", "state", "aero_coefficients"):
            builder.Connect(plant.GetOutputPort(name), regressors.GetInputPort(name))
        builder.ExportInput(regressors.GetInputPort("controls"))
    builder.ExportInput(plant.GetInputPort("controls"))
    builder.ExportInput(plant.GetInputPort("wind_ned"))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant.set_state(plant.GetMyMutableContextFromRoot(context), state)
    for i in range(diagram.num_input_ports() - 1):
        diagram.get_input_port(i).FixValue(context, controls)
    diagram.get_input_port(diagram.num_input_ports() - 1).FixValue(context, [2.0, -3.0, 0.5])
    for coefficient, system in systems.items():
        sub = system.GetMyContextFromRoot(context)
        row = system.GetOutputPort("regressors").Eval(sub)
        theta = np.array([params.derivatives[n] for n in system.names])
        observed = system.GetOutputPort("observation").Eval(sub)[0]
        assert row @ theta == pytest.approx(observed, abs=1e-12), coefficient
    with pytest.raises(ValueError, match="^coefficient:"):
        AeroRegressors(params, "CQ")
