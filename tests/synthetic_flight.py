"""A small open-loop Aerosonde flight with orthogonal multisine inputs, an optional
effect injected through the plant's external wrench, and white sensor noise."""

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.identification.samples.isolation import isolate_coefficients
from drake_uav.optimization.trim import trim
from drake_uav.systems.disturbances import AerodynamicIncrement
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.vehicles.fixed_wing import aerosonde

NOISE = {"specific_force": 0.05, "rates": np.radians(0.1), "airspeed": 0.1,
         "angles": np.radians(0.1)}


def synthetic_samples(increment=None, seed=0, duration=100.0, noise=True):
    """(params, AeroSamples, truth dict) of a 50 Hz flight."""
    rng = np.random.default_rng(seed)
    params, truth = synthetic_flight(rng, increment, duration)
    return params, measured_samples(params, truth, rng if noise else None), truth


def synthetic_flight(rng, increment=None, duration=100.0):
    """(params, truth dict) of a 50 Hz flight; ``rng`` draws the multisine phases."""
    params = aerosonde()
    level = trim(params, 25.0)
    t = np.arange(0.0, duration + 0.02, 0.02)
    u = np.tile(level.controls[:, None], (1, len(t)))
    for j, amplitude in enumerate((0.05, 0.06, 0.05, 0.15)):
        omegas = 2 * np.pi * np.arange(j + 1, 60, 4) / 20.0
        phases = rng.uniform(0, 2 * np.pi, len(omegas))
        signal = sum(np.sin(w * t + ph) for w, ph in zip(omegas, phases, strict=True))
        u[j] += amplitude * signal / np.std(signal) / 2
    u[3] = np.clip(u[3], 0.05, 1.0)
    builder = DiagramBuilder()
    plant = builder.AddSystem(FixedWingPlant(params))
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, u)))
    builder.Connect(source.get_output_port(), plant.GetInputPort("controls"))
    if increment is not None:
        effect = builder.AddSystem(AerodynamicIncrement(params, increment))
        builder.Connect(plant.GetOutputPort("air_data"), effect.GetInputPort("air_data"))
        builder.Connect(plant.GetOutputPort("state"), effect.GetInputPort("state"))
        builder.Connect(source.get_output_port(), effect.GetInputPort("controls"))
        builder.Connect(effect.GetOutputPort("wrench"), plant.GetInputPort("external_wrench"))
    logs = {n: LogVectorOutput(plant.GetOutputPort(n), builder, 0.02)
            for n in ("state", "air_data", "specific_force", "euler")}
    control_log = LogVectorOutput(source.get_output_port(), builder, 0.02)
    simulator = Simulator(builder.Build())
    plant.set_state(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()),
                    level.state)
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    d = {k: log.FindLog(context).data().T for k, log in logs.items()}
    time = logs["state"].FindLog(context).sample_times()
    return params, dict(d, controls=control_log.FindLog(context).data().T, time=time)


def measured_samples(params, truth, rng=None):
    """AeroSamples of the ``truth`` flight with white sensor noise drawn by ``rng``
    (None: exact sensors)."""
    d = truth
    force, rates, air = d["specific_force"], d["state"][:, 10:13], d["air_data"]
    if rng is not None:
        force = force + rng.normal(0, NOISE["specific_force"], force.shape)
        rates = rates + rng.normal(0, NOISE["rates"], rates.shape)
        air = air + rng.normal(0, 1, air.shape) * np.array(
            [NOISE["airspeed"], NOISE["angles"], NOISE["angles"]])
    euler = d["euler"]
    u = d["controls"]
    # The controls are linear between the samples: the trapezoid is their interval average.
    interval_controls = np.vstack([0.5 * (u[1:] + u[:-1]), u[-1:]])
    return isolate_coefficients(
        params, d["time"], force, rates, air, u, moment_controls=interval_controls,
        signals={"roll": euler[:, 0], "pitch": euler[:, 1], "yaw": euler[:, 2],
                 "height": -d["state"][:, 2]})
