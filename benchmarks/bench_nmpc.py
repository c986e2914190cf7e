"""Per-step solve time of the tracking NMPC over a closed loop, against a CasADi reference.

Flies the bundled 6-waypoint trajectory (hexacopter, 0.5 m / 10 deg initial offset)
for ``--duration`` seconds with four controllers of the same OCP (T_p = 1 s, 40
RK4 multiple-shooting intervals, the same weights, thrust bounds and terminal
level set):

* drake_uav RTI (one SQP step, Clarabel) and full NLP (SQP to convergence);
* CasADi + IPOPT (full NLP) and CasADi ``sqpmethod`` limited to one iteration.

The CasADi model is not a second copy of the equations: the plant function
``multirotor_dynamics`` and ``state_error`` are traced with Drake symbolic variables
and their expressions evaluated with CasADi symbols. The plant is integrated
with RK4 at 5 ms between 40 Hz control steps. Prints median / p95 / max per
mode, the RMSE after 2 s and the ratios against CasADi.

    python benchmarks/bench_nmpc.py [--duration 20] [--modes rti,nlp,casadi_ipopt,casadi_sqp]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from pydrake.symbolic import Expression, Variable

from drake_uav.diagrams.tracking import build_terminal_set, tracking_reference
from drake_uav.model.attitude_error import state_error
from drake_uav.model.multirotor import motor_wrench, multirotor_derivatives, multirotor_dynamics
from drake_uav.model.rotations import euler_to_quat, quat_multiply
from drake_uav.optimization.nmpc import NmpcSettings, TrackingNmpc
from drake_uav.vehicles.multirotor import hexacopter


def _to_casadi(fn, sizes):
    """A CasADi ``Function`` of ``fn`` traced with Drake symbolic inputs of ``sizes``."""
    import casadi as ca

    names = [[f"a{i}_{j}" for j in range(n)] for i, n in enumerate(sizes)]
    exprs = fn(*[np.array([Expression(Variable(v)) for v in vs]) for vs in names])
    syms = [ca.SX.sym(f"a{i}", n) for i, n in enumerate(sizes)]
    scope = {v: syms[i][j] for i, vs in enumerate(names) for j, v in enumerate(vs)}
    scope.update(pow=ca.power, sqrt=ca.sqrt, sin=ca.sin, cos=ca.cos, abs=ca.fabs,
                 max=ca.fmax, min=ca.fmin)
    text = [e.to_string() if isinstance(e, Expression) else repr(float(e)) for e in exprs]
    out = [eval(s, {"__builtins__": {}}, scope) for s in text]
    return ca.Function("f", syms, [ca.vertcat(*out)])


class CasadiNmpc:
    """The same OCP in CasADi (multiple shooting, RK4, terminal ellipsoid constraint)."""

    def __init__(self, params, terminal, settings: NmpcSettings, method: str):
        import casadi as ca

        self.terminal, self.settings = terminal, settings
        n, N = params.num_motors, settings.nodes
        self.N, self.h = N, settings.horizon / N
        f = _to_casadi(lambda x, u: multirotor_dynamics(x, motor_wrench(u, params), params),
                       [13, n])
        err = _to_casadi(state_error, [13, 13])
        X, U = ca.SX.sym("X", 13, N + 1), ca.SX.sym("U", n, N)
        x0, XR, UR = ca.SX.sym("x0", 13), ca.SX.sym("XR", 13, N + 1), ca.SX.sym("UR", n, N)
        Pt, level = ca.SX.sym("P", 12, 12), ca.SX.sym("level")
        Q, R, h = np.diag(settings.state_weight), settings.input_weight * np.eye(n), self.h
        cost, g = 0, [X[:, 0] - x0]
        for j in range(N):
            x, u = X[:, j], U[:, j]
            k1 = f(x, u)
            k2 = f(x + h / 2 * k1, u)
            k3 = f(x + h / 2 * k2, u)
            k4 = f(x + h * k3, u)
            g.append(x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4) - X[:, j + 1])
            e = err(X[:, j + 1], XR[:, j + 1])
            du = u - UR[:, j]
            cost += h * (ca.mtimes([e.T, Q, e]) + ca.mtimes([du.T, R, du]))
        eN = err(X[:, N], XR[:, N])
        g.append(ca.mtimes([eN.T, Pt, eN]) - level**2)
        self.ng = 13 * (N + 1)
        nlp = {"x": ca.vertcat(ca.vec(X), ca.vec(U)), "f": cost, "g": ca.vertcat(*g),
               "p": ca.vertcat(x0, ca.vec(XR), ca.vec(UR), ca.vec(Pt), level)}
        if method == "ipopt":
            opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                    "ipopt.max_iter": 100}
            self.solver = ca.nlpsol("nmpc", "ipopt", nlp, opts)
        else:
            opts = {"max_iter": 1, "qpsol": "qrqp", "print_header": False, "print_status": False,
                    "print_iteration": False, "print_time": False, "error_on_fail": False,
                    "qpsol_options": {"print_iter": False, "print_header": False,
                                      "error_on_fail": False}}
            self.solver = ca.nlpsol("nmpc", "sqpmethod", nlp, opts)
        f_max = params.f_max
        self.lbx = np.concatenate([np.full(13 * (N + 1), -np.inf), np.zeros(n * N)])
        self.ubx = np.concatenate([np.full(13 * (N + 1), np.inf), np.full(n * N, f_max)])
        self.lbg = np.concatenate([np.zeros(self.ng), [-np.inf]])
        self.ubg = np.zeros(self.ng + 1)
        self.n, self.guess, self.lam = n, None, None

    def solve(self, t, x):
        N, n, h = self.N, self.n, self.h
        xr, ur = self.terminal.reference.at(t + h * np.arange(N + 1))
        if x[3:7] @ xr[0, 3:7] < 0:
            x = np.concatenate([x[:3], -x[3:7], x[7:]])
        Pt, _, level = self.terminal.matrices_at(t + self.settings.horizon)
        # casadi vec() is column-major: column j of XR is xr[j], so vec(XR) = xr.ravel()
        p = np.concatenate([x, xr.ravel(), ur[:-1].ravel(), Pt.ravel("F"), [level]])
        if self.guess is None:
            X0 = xr.copy()
            X0[0] = x
            self.guess = np.concatenate([X0.ravel(), ur[:-1].ravel()])
        start = time.perf_counter()
        kw = dict(x0=self.guess, p=p, lbx=self.lbx, ubx=self.ubx, lbg=self.lbg, ubg=self.ubg)
        if self.lam is not None:
            kw.update(lam_g0=self.lam)
        sol = self.solver(**kw)
        elapsed = time.perf_counter() - start
        z = np.array(sol["x"]).ravel()
        X = z[:13 * (N + 1)].reshape(N + 1, 13)
        U = z[13 * (N + 1):].reshape(N, n)
        self.guess = np.concatenate([np.vstack([X[1:], X[-1:]]).ravel(),
                                     np.vstack([U[1:], U[-1:]]).ravel()])
        self.lam = np.array(sol["lam_g"]).ravel()
        stats = self.solver.stats()
        # one SQP iteration ends at the iteration limit by design: only a QP failure counts
        ok = stats.get("success", False) or \
            stats.get("return_status") == "Maximum_iterations_exceeded"
        return np.clip(U[0], 0.0, self.terminal.params.f_max), elapsed, ok


def _closed_loop(controller, params, terminal, duration, x0):
    x, t, times, errors, failures = x0.copy(), 0.0, [], [], 0
    period, sub = 0.025, 5
    while t < duration - 1e-9:
        u, elapsed, ok = controller(t, x)
        times.append(elapsed)
        failures += not ok
        h = period / sub
        for _ in range(sub):
            def f(s, u=u):
                return multirotor_derivatives(s, u, params)
            k1 = f(x)
            k2 = f(x + h / 2 * k1)
            k3 = f(x + h / 2 * k2)
            k4 = f(x + h * k3)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += period
        xr, _ = terminal.reference.at(t)
        errors.append((t, np.linalg.norm(x[:3] - xr[:3])))
    e = np.array(errors)
    rmse = float(np.sqrt(np.mean(e[e[:, 0] >= 2.0, 1] ** 2)))
    return np.array(times), rmse, failures


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--modes", default="rti,nlp,casadi_ipopt,casadi_sqp")
    args = parser.parse_args(argv)
    params = hexacopter()
    t0 = time.perf_counter()
    terminal = build_terminal_set(params, tracking_reference(params))
    print(f"terminal sets: {time.perf_counter() - t0:.1f} s")
    x0 = terminal.reference.state[0].copy()
    x0[:3] += [0.3, 0.4, 0.0]
    x0[3:7] = quat_multiply(x0[3:7], euler_to_quat([np.radians(10.0), 0.0, 0.0]))
    stats = {}
    for mode in args.modes.split(","):
        settings = NmpcSettings(mode=mode if mode in ("rti", "nlp") else "rti")
        if mode.startswith("casadi"):
            ctrl = CasadiNmpc(params, terminal, settings, mode.split("_")[1]).solve
        else:
            mpc = TrackingNmpc(params, terminal, settings)

            def ctrl(t, x, mpc=mpc):
                r = mpc.solve(t, x)
                return r.thrusts, r.solve_time, r.success
        times, rmse, failures = _closed_loop(ctrl, params, terminal, args.duration, x0)
        stats[mode] = np.median(times)
        print(f"{mode:13s} median {1e3 * np.median(times):7.2f} ms  p95 "
              f"{1e3 * np.percentile(times, 95):7.2f} ms  max {1e3 * times.max():7.2f} ms  "
              f"RMSE after 2 s {100 * rmse:.3f} cm  failed steps {failures}", flush=True)
    for mine, ref in (("rti", "casadi_sqp"), ("nlp", "casadi_ipopt"), ("rti", "casadi_ipopt")):
        if mine in stats and ref in stats:
            print(f"median ratio {mine} / {ref}: {stats[mine] / stats[ref]:.2f}")


if __name__ == "__main__":
    main()
