"""Cost of the EKFs: time per filter step and real-time factor of a flight with the EKF inside.

Step cost: CPU time of predict + update over 20 s of a logged identification flight,
for the core (one filter; a batch of 20 filters in lockstep; the AutoDiffXd backend for
reference) and for the LeafSystem's periodic update as the simulator calls it (port
evaluation, sample bookkeeping, GPS latency, attitude smoothing, predict + update; the
cost of fixing the input values is measured alone and taken off). Repeated; minimum and
median. Target: <= 100 us per filter step. Real-time factor: 60 s of the identification
flight (plant, Dryden wind, sensors, safety pilot, multisine excitation, loggers),
without and with the AirDataEkf at 100 Hz added through ``extend``. Target: >= 50x.

Each headline figure is also printed as a FIGURE line (benchmarks/figures.py); ``--quick``
skips the batch and AutoDiffXd reference costs, repeats twice and flies 20 s flights once.

Run: python benchmarks/bench_estimation.py [--quick]
"""

import time

import numpy as np

from drake_uav.diagrams.identification_flight import build_identification_flight, fly
from drake_uav.estimation import AirDataModel, ModelBasedAirDataModel, ParameterModel
from drake_uav.estimation.ekf import ExtendedKalmanFilter
from drake_uav.systems.estimators import (
    AirDataEkf,
    EkfSystemParams,
    ModelBasedAirDataEkf,
    ParameterEkf,
)
from drake_uav.vehicles.fixed_wing import aerosonde
from drake_uav.vehicles.sensors import SensorSuiteParams

STEP_TARGET_US = 100.0
RTF_TARGET = 50.0
STEADY_WIND = (4.0, -3.0, 0.0)
SAMPLE_PERIOD = 0.01  # s, the flight's sensor and EKF period


def step_cost_us(ekf: ExtendedKalmanFilter, data, batch: int = 1, steps: int = 2000) -> float:
    """CPU microseconds per filter per step (input smoothing where the model has it,
    predict + update) over logged samples."""
    U, Y, A = data.inputs, data.measurements, data.available
    x, P = ekf.model.initial_state(U[0], Y[0], A[0]), ekf.initial_covariance
    if batch > 1:  # the same flight for every filter of the batch
        U, Y, A = (np.repeat(a[:, None], batch, axis=1) for a in (U, Y, A))
        x, P = np.repeat(x[None], batch, axis=0), np.repeat(P[None], batch, axis=0)
    dt = data.time[1] - data.time[0]
    smooth = ekf.model.smooth_inputs if ekf.model.smoothed_inputs else None
    u_previous = U[0]
    start = time.process_time()
    for k in range(1, steps + 1):
        u = U[k] if smooth is None else smooth(u_previous, U[k], dt)
        x, P = ekf.predict(x, P, ekf.midpoint_input(u_previous, u), dt)
        result = ekf.update(x, P, u, Y[k], A[k])
        x, P, u_previous = result.x, result.P, u
    return (time.process_time() - start) / steps / batch * 1e6


def leaf_step_cost_us(system, inputs: dict[str, np.ndarray], steps: int = 2000,
                      warmup: int = 100) -> float:
    """CPU microseconds per periodic update of an EKF LeafSystem fed with logged rows."""
    context = system.CreateDefaultContext()
    ports = [(system.GetInputPort(name), rows) for name, rows in inputs.items()]

    def advance(k: int, update: bool) -> None:
        for port, rows in ports:
            port.FixValue(context, rows[k])
        if update:
            values = system.EvalUniquePeriodicDiscreteUpdate(context)
            context.SetDiscreteState(values.get_vector(0).value())

    for k in range(warmup):
        advance(k, True)
    started = context.get_discrete_state_vector().CopyToVector()

    def run(update: bool) -> float:
        context.SetDiscreteState(started)
        start = time.process_time()
        for k in range(warmup, warmup + steps):
            advance(k, update)
        return time.process_time() - start

    return (run(True) - run(False)) / steps * 1e6


def repeated(measure, repeats: int) -> tuple[float, float]:
    """(minimum, median) of ``repeats`` measurements."""
    values = [measure() for _ in range(repeats)]
    return min(values), float(np.median(values))


def sensor_rows(log) -> dict[str, np.ndarray]:
    """Logged rows for the EKF systems' input ports."""
    return {
        "imu": log.stack(["imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r"]),
        "attitude": log.stack(["att_roll", "att_pitch", "att_yaw"]),
        "gps": log.stack(["gps_pn", "gps_pe", "gps_pd", "gps_vn", "gps_ve", "gps_vd"]),
        "pitot": log.stack(["pitot_qbar", "pitot_airspeed"]),
        "vanes": log.stack(["vane_alpha", "vane_beta"]),
        "controls": log.stack(["cmd_elevator", "cmd_aileron", "cmd_rudder", "cmd_throttle"]),
        "air_data": log.stack(["pitot_airspeed", "vane_alpha", "vane_beta"]),
    }


def flight_rtf(with_ekf: bool, duration: float = 60.0, repeats: int = 3) -> float:
    """Real-time factor (CPU, best of ``repeats``) of the identification flight, optionally
    with an AirDataEkf on its sensors (added through ``extend``)."""
    params = aerosonde()

    def add_ekf(builder, ports):
        sensors = SensorSuiteParams.seed_table7(air_density=params.rho)
        ekf = builder.AddSystem(AirDataEkf(EkfSystemParams(params, sensors)))
        for name in ("imu", "attitude", "gps", "pitot", "vanes"):
            builder.Connect(ports[name], ekf.GetInputPort(name))

    flight = build_identification_flight(params, "light", steady_wind=STEADY_WIND, seed=1,
                                         duration=duration,
                                         extend=add_ekf if with_ekf else None)
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        flight.simulate()
        best = min(best, time.process_time() - start)
    return duration / best


FIGURE_KEYS = {"AirDataEkf (model-free)": "airdata", "AirDataEkf": "airdata",
               "ModelBasedAirDataEkf": "model_based_airdata",
               "ParameterEkf longitudinal": "parameter_longitudinal",
               "ParameterEkf lateral": "parameter_lateral",
               "ParameterEkf (two filters)": "parameter"}
"""Names of the FIGURE lines by label."""


def main() -> None:
    import argparse

    from figures import figure

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="no batch or AutoDiffXd costs, 2 repeats, 20 s flights flown once")
    quick = parser.parse_args().quick
    params = aerosonde()
    log = fly(params, "light", steady_wind=STEADY_WIND, seed=2, duration=25.0)
    repeats = 2 if quick else 7
    filters = [("AirDataEkf (model-free)", AirDataModel(params), {}),
               ("ModelBasedAirDataEkf", ModelBasedAirDataModel(params), {}),
               ("ParameterEkf longitudinal", ParameterModel(params, "longitudinal"),
                {"turbulence": "light"}),
               ("ParameterEkf lateral", ParameterModel(params, "lateral"),
                {"turbulence": "light"})]
    print(f"EKF core step cost (predict + update), CPU time per filter, min / median of "
          f"{repeats}:")
    for label, model, options in filters:
        noise = model.default_noise(**options)
        ekf = ExtendedKalmanFilter(model, noise)
        data = model.log_data(log)
        low, median = repeated(lambda ekf=ekf, data=data: step_cost_us(ekf, data), repeats)
        figure(f"ekf_core_us_{FIGURE_KEYS[label]}", low, "us", "lower")
        if quick:
            print(f"  {label:26s} {low:6.1f} / {median:6.1f} us")
            continue
        batch = step_cost_us(ekf, data, batch=20, steps=500)
        reference = ExtendedKalmanFilter(model, noise, backend="autodiff")
        autodiff = step_cost_us(reference, data, steps=100)
        operations = ekf.dynamics.operation_count + ekf.measurement.operation_count
        print(f"  {label:26s} {low:6.1f} / {median:6.1f} us ({low / STEP_TARGET_US:4.2f} of "
              f"the {STEP_TARGET_US:.0f} us target); in a batch of 20: {batch:6.1f} us; "
              f"AutoDiffXd Jacobians: {autodiff:7.1f} us ({autodiff / low:4.1f}x); "
              f"{operations} compiled operations")
    rows = sensor_rows(log)
    sensors = ("imu", "attitude", "gps", "pitot", "vanes")
    systems = [("AirDataEkf", AirDataEkf(EkfSystemParams(params)), sensors, 1),
               ("ModelBasedAirDataEkf", ModelBasedAirDataEkf(EkfSystemParams(params)),
                sensors + ("controls",), 1),
               ("ParameterEkf (two filters)",
                ParameterEkf(EkfSystemParams(params), turbulence="light"),
                ("air_data", "imu", "attitude", "controls"), 2)]
    print(f"LeafSystem periodic update, CPU time per step, min / median of {repeats}:")
    for label, system, ports, count in systems:
        inputs = {name: rows[name] for name in ports}
        low, median = repeated(lambda s=system, i=inputs: leaf_step_cost_us(s, i), repeats)
        print(f"  {label:26s} {low:6.1f} / {median:6.1f} us per step, {low / count:6.1f} us "
              f"per filter ({low / count / STEP_TARGET_US:4.2f} of the target)")
        figure(f"ekf_leaf_us_{FIGURE_KEYS[label]}", low / count, "us", "lower")
    duration, flights = (20.0, 1) if quick else (60.0, 3)
    without = flight_rtf(False, duration, flights)
    with_ekf = flight_rtf(True, duration, flights)
    print(f"identification flight (plant, Dryden, sensors, pilot, excitation, loggers), "
          f"{duration:.0f} s: "
          f"{without:6.1f}x real time")
    added_us = 1e6 * SAMPLE_PERIOD * (1.0 / with_ekf - 1.0 / without)
    print(f"  with the AirDataEkf at 100 Hz:  {with_ekf:6.1f}x real time "
          f"({with_ekf / RTF_TARGET:4.2f} of the {RTF_TARGET:.0f}x target; EKF share "
          f"{1.0 - with_ekf / without:4.0%} of the run time, {added_us:5.1f} us added per "
          f"{SAMPLE_PERIOD * 1e3:.0f} ms tick)")
    figure("flight_rtf", without, "x")
    figure("flight_airdata_ekf_rtf", with_ekf, "x")
    figure("airdata_ekf_tick_us", added_us, "us", "lower")


if __name__ == "__main__":
    main()
