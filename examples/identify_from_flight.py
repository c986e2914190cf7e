"""Identify the Aerosonde from a simulated flight whose lift bends away at high alpha.

The flight has a stall-onset effect (C_L -= 30 alpha^3) that the catalog model
does not have. The main job fits the catalog structure, finds the missing effect
in the residual, refits, and writes a report; the identified derivatives are
printed next to the true ones.

Run: python examples/identify_from_flight.py [report_folder]   (default out/identify_from_flight)
     python examples/identify_from_flight.py --quick   (a 60 s flight instead of 150 s)
"""

import argparse

import numpy as np

from drake_uav.diagrams import fly
from drake_uav.identification.pipeline import identify
from drake_uav.reporting.identification_report import write_report
from drake_uav.vehicles import aerosonde

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("report", nargs="?", default="out/identify_from_flight",
                    help="report folder")
parser.add_argument("--quick", action="store_true", help="a 60 s flight instead of 150 s")
args = parser.parse_args()

params = aerosonde()
log = fly(params, turbulence="light", seed=11, duration=60.0 if args.quick else 150.0,
          disturbance=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0))
run = identify(log, params, progress=lambda message: print("...", message))
result = run.discovery
print(result.message)
for effect in result.found:
    print(f"  {effect.name}: {effect.explanation}")
    for term, (value, sigma) in effect.parameters.items():
        print(f"    {term} = {value:+.3f} +- {sigma:.3f}")

print("\nforce derivatives after the update (truth, estimate +- sigma):")
for k in ("CL", "CD", "CY"):
    fit = result.final[k].result
    for i, name in enumerate(fit.names):
        if ":" not in name:
            truth = params.derivative(name)
            mark = "" if abs(fit.estimate[i] - truth) <= 2 * fit.sigma[i] else "  (> 2 sigma)"
            print(f"  {name:>12}: {truth:+.4f}  {fit.estimate[i]:+.4f} +- {fit.sigma[i]:.4f}"
                  f"{mark}")

before, after = result.rms_change()["CL"]
print(f"\nheld-out C_L equation-error RMS: {before:.4f} -> {after:.4f}")
mae = np.degrees(run.reconstruction_before.mae[1]), np.degrees(run.reconstruction_after.mae[1])
print(f"reconstruction MAE of alpha: {mae[0]:.3f} deg -> {mae[1]:.3f} deg")
print(f"report: {write_report(run, args.report) / 'report.html'}")
