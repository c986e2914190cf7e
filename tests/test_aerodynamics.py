import numpy as np
import pytest
from pydrake.symbolic import Evaluate, Variable

import drake_uav.model as aero
from drake_uav.vehicles.fixed_wing import aerosonde


def _condition(n=None):
    rng = np.random.default_rng(3)
    size = n or None
    return aero.AeroCondition(
        airspeed=rng.uniform(15, 30, size), alpha=rng.uniform(-0.1, 0.2, size),
        beta=rng.uniform(-0.1, 0.1, size), p=rng.uniform(-1, 1, size),
        q=rng.uniform(-1, 1, size), r=rng.uniform(-1, 1, size),
        elevator=rng.uniform(-0.2, 0.2, size), aileron=rng.uniform(-0.2, 0.2, size),
        rudder=rng.uniform(-0.2, 0.2, size),
    )


def test_air_data_round_trip_seed_s0_eq_2_12_to_2_14():
    Va, alpha, beta = 23.0, 0.12, -0.07
    u, v, w = aero.velocity_from_air_data(Va, alpha, beta)
    np.testing.assert_allclose(aero.air_data_from_velocity(u, v, w), (Va, alpha, beta),
                               rtol=1e-14)
    # beta = asin(v / Va), alpha = atan(w / u)
    assert np.isclose(np.arcsin(v / Va), beta) and np.isclose(np.arctan(w / u), alpha)


def test_lift_drag_body_axes_round_trip():
    CX, CZ = aero.lift_drag_to_body(0.8, 0.05, 0.1)
    np.testing.assert_allclose(aero.body_to_lift_drag(CX, CZ, 0.1), (0.8, 0.05), rtol=1e-14)
    # At zero alpha lift points along -z and drag along -x.
    np.testing.assert_allclose(aero.lift_drag_to_body(1.0, 0.1, 0.0), (-0.1, -1.0))


def test_coefficients_equal_the_written_out_seed_model():
    p = aerosonde()
    d = p.derivatives
    cond = _condition()
    model = aero.CoefficientModel(d)
    CL, CD, CY, Cl, Cm, Cn = model.evaluate(cond, p.b, p.c)
    qn = p.c * cond.q / (2 * cond.airspeed)
    pn, rn = p.b * cond.p / (2 * cond.airspeed), p.b * cond.r / (2 * cond.airspeed)
    assert CL == pytest.approx(d["CL_0"] + d["CL_alpha"] * cond.alpha + d["CL_q"] * qn
                               + d["CL_elevator"] * cond.elevator)
    assert CD == pytest.approx(d["CD_0"] + d["CD_alpha"] * cond.alpha
                               + d["CD_alpha2"] * cond.alpha**2)
    assert Cn == pytest.approx(d["Cn_beta"] * cond.beta + d["Cn_p"] * pn + d["Cn_r"] * rn
                               + d["Cn_aileron"] * cond.aileron + d["Cn_rudder"] * cond.rudder)
    assert Cm == pytest.approx(d["Cm_0"] + d["Cm_alpha"] * cond.alpha + d["Cm_q"] * qn
                               + d["Cm_elevator"] * cond.elevator)
    assert CY == pytest.approx(d["CY_beta"] * cond.beta + d["CY_rudder"] * cond.rudder)
    assert Cl == pytest.approx(d["Cl_beta"] * cond.beta + d["Cl_p"] * pn + d["Cl_r"] * rn
                               + d["Cl_aileron"] * cond.aileron + d["Cl_rudder"] * cond.rudder)


def test_regressor_matrix_times_parameters_is_the_model_for_sample_arrays():
    p = aerosonde()
    cond = _condition(50)
    model = aero.CoefficientModel(p.derivatives)
    for k, coefficient in enumerate(aero.COEFFICIENTS):
        names = model.term_names(coefficient)
        X = aero.regressor_matrix(names, cond, p.b, p.c)
        assert X.shape == (50, len(names))
        theta = np.array([p.derivatives[n] for n in names])
        np.testing.assert_allclose(X @ theta, model.evaluate(cond, p.b, p.c)[k], atol=1e-14)


def test_symbolic_model_is_linear_in_parameters():
    alpha, q = Variable("alpha"), Variable("q")
    cond = aero.AeroCondition(airspeed=20.0, alpha=alpha, beta=0.0, p=0.0, q=q, r=0.0)
    model = aero.CoefficientModel({"CL_0": 0.2, "CL_alpha": 4.0, "CL_q": 5.0})
    CL = model.coefficient("CL", cond, 2.0, 0.5)
    assert Evaluate(np.array([CL]), {alpha: 0.1, q: 0.4})[0, 0] == pytest.approx(
        0.2 + 0.4 + 5.0 * 0.5 * 0.4 / 40.0)


def test_unknown_derivative_name_is_rejected_with_its_name():
    with pytest.raises(ValueError, match="CL_wobble"):
        aero.validate_derivative_names(["CL_alpha", "CL_wobble"])
    with pytest.raises(ValueError, match="Cx_alpha"):
        aero.CoefficientModel({"Cx_alpha": 1.0})
