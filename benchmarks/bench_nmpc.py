"""Per-step solve time of the tracking NMPC over a closed loop, against a CasADi reference.

Flies the bundled 6-waypoint trajectory (hexacopter, 0.5 m / 10 deg initial offset)
for ``--duration`` seconds with four controllers of the same OCP (T_p = 1 s, 40
RK4 multiple-shooting intervals, the same weights, thrust bounds and terminal
level set):

* drake_uav RTI (one SQP step) and full NLP (SQP to convergence), each with its QPs
  solved by the Riccati recursion (Clarabel when a bound is active) and, as
  ``rti_clarabel`` / ``nlp_clarabel``, with every QP given to Clarabel;
* CasADi + IPOPT (full NLP) and CasADi ``sqpmethod`` limited to one iteration.

The CasADi model is not a second copy of the equations: the plant function
``multirotor_dynamics`` and ``state_error`` are traced with Drake symbolic variables
and their expressions evaluated with CasADi symbols. The plant is integrated
with RK4 at 5 ms between 40 Hz control steps. All controllers fly in lockstep
(each its own loop; at every control step each is timed in turn), so the load of a
shared machine falls on all of them alike. Prints median / p95 / max of the wall
time of each step and the median of its process CPU time per mode, the RMSE after
2 s, which solver path the steps took, and the ratios of the medians.

    python benchmarks/bench_nmpc.py [--duration 20] [--modes rti,nlp,casadi_ipopt,...] [--quick]

Without CasADi (pip ``casadi``, the optional ``[bench]`` extra) its modes are skipped with a
note and the others fly. ``--quick`` flies 3 s with a coarser terminal level.
"""

from __future__ import annotations

import argparse
import importlib.util
import time

import numpy as np
from figures import figure
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


def _plant_step(x, u, params, period=0.025, sub=5):
    """RK4 at ``period / sub`` of the plant (with its thrust saturation) under ``u``."""
    h = period / sub
    for _ in range(sub):
        def f(s, u=u):
            return multirotor_derivatives(s, u, params)
        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def _closed_loops(controllers: dict, params, terminal, duration, x0) -> dict:
    """Every controller flies its own copy of the loop, all in lockstep: at each control
    step each one is timed in turn, so load on a shared machine hits all alike. Per
    controller: wall and CPU times per step [s], RMSE after 2 s [m], failed steps, and
    the count of each solver status."""
    period = 0.025
    runs = {name: {"x": x0.copy(), "wall": [], "cpu": [], "errors": [], "failures": 0,
                   "paths": {}} for name in controllers}
    t = 0.0
    while t < duration - 1e-9:
        xr, _ = terminal.reference.at(t + period)
        for name, controller in controllers.items():
            run = runs[name]
            cpu = time.process_time()
            u, elapsed, ok, path = controller(t, run["x"])
            run["cpu"].append(time.process_time() - cpu)
            run["wall"].append(elapsed)
            run["failures"] += not ok
            run["paths"][path] = run["paths"].get(path, 0) + 1
            run["x"] = _plant_step(run["x"], u, params, period)
            run["errors"].append((t + period, np.linalg.norm(run["x"][:3] - xr[:3])))
        t += period
    for run in runs.values():
        e = np.array(run.pop("errors"))
        run["rmse"] = float(np.sqrt(np.mean(e[e[:, 0] >= 2.0, 1] ** 2)))
        run["wall"], run["cpu"] = np.array(run["wall"]), np.array(run["cpu"])
    return runs


def _controller(mode, params, terminal):
    """``(t, x) -> (thrusts, wall time, ok, status name)`` of one benchmarked mode."""
    if mode.startswith("casadi"):
        casadi = CasadiNmpc(params, terminal, NmpcSettings(), mode.split("_")[1])

        def ctrl(t, x):
            u, elapsed, ok = casadi.solve(t, x)
            return u, elapsed, ok, "casadi"
        return ctrl
    base, _, qp = mode.partition("_")
    mpc = TrackingNmpc(params, terminal, NmpcSettings(mode=base, qp_solver=qp or "riccati"))

    def ctrl(t, x):
        r = mpc.solve(t, x)
        path = "Clarabel" if r.solver_status.startswith("k") else r.solver_status
        return r.thrusts, r.solve_time, r.success, path
    return ctrl


MODES = "rti,nlp,rti_clarabel,nlp_clarabel,casadi_ipopt,casadi_sqp"
RATIOS = (("rti", "casadi_sqp"), ("nlp", "casadi_ipopt"), ("rti", "casadi_ipopt"),
          ("rti", "rti_clarabel"), ("nlp", "nlp_clarabel"))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--modes", default=MODES)
    parser.add_argument("--quick", action="store_true",
                        help="a 3 s flight, a coarser terminal level")
    args = parser.parse_args(argv)
    if args.quick:
        args.duration = 3.0
    modes = args.modes.split(",")
    if importlib.util.find_spec("casadi") is None:
        skipped = [m for m in modes if m.startswith("casadi")]
        modes = [m for m in modes if not m.startswith("casadi")]
        if skipped:
            print(f"CasADi is not installed: {', '.join(skipped)} skipped "
                  "(pip install 'drake_uav[bench]' or casadi)")
    params = hexacopter()
    t0 = time.perf_counter()
    coarse = {"samples": 32, "shrink_interval": 1.0} if args.quick else {}
    terminal = build_terminal_set(params, tracking_reference(params), **coarse)
    print(f"terminal sets: {time.perf_counter() - t0:.1f} s")
    x0 = terminal.reference.state[0].copy()
    x0[:3] += [0.3, 0.4, 0.0]
    x0[3:7] = quat_multiply(x0[3:7], euler_to_quat([np.radians(10.0), 0.0, 0.0]))
    runs = _closed_loops({m: _controller(m, params, terminal) for m in modes}, params,
                         terminal, args.duration, x0)
    for mode, run in runs.items():
        w, c = 1e3 * run["wall"], 1e3 * run["cpu"]
        print(f"{mode:13s} wall median {np.median(w):7.2f} ms  p95 {np.percentile(w, 95):7.2f}"
              f" ms  max {w.max():7.2f} ms | CPU median {np.median(c):7.2f} ms  p95 "
              f"{np.percentile(c, 95):7.2f} ms | RMSE after 2 s {100 * run['rmse']:.3f} cm  "
              f"failed steps {run['failures']}  {run['paths']}", flush=True)
        figure(f"nmpc_{mode}_median_wall", np.median(w), "ms", "lower")
        figure(f"nmpc_{mode}_median_cpu", np.median(c), "ms", "lower")
    for mine, ref in RATIOS:
        if mine in runs and ref in runs:
            wall = np.median(runs[mine]["wall"]) / np.median(runs[ref]["wall"])
            cpu = np.median(runs[mine]["cpu"]) / np.median(runs[ref]["cpu"])
            print(f"median ratio {mine} / {ref}: wall {wall:.3f}, CPU {cpu:.3f}")
            figure(f"nmpc_ratio_{mine}_over_{ref}", cpu, "x", "lower")


if __name__ == "__main__":
    main()
