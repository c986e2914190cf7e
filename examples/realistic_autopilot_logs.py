"""Write a simulated flight as a realistic ArduPilot .bin and PX4 .ulg log, and read them.

The Aerosonde flies 120 s of multisine excitation in light turbulence with an
effect its model lacks (lift bending away at high alpha: C_L -= 30 alpha^3). The
logs get a ground segment, a take-off run, a late GPS fix, PWM 0 before arming,
a reversed servo, +-400 us throws, a 50 Hz IMU, 1 Hz optional topics and a
truncated tail; no vanes, no truth. Reading them back shows what the readers make
of it; `drake-uav identify FOLDER/flight.bin` runs the main job on one, and
FOLDER/flight.csv (the same flight with vanes and truth) is the reference to compare with.

Run: python examples/realistic_autopilot_logs.py [folder]   (default out/realistic_autopilot_logs)
     python examples/realistic_autopilot_logs.py --quick   (a 40 s flight instead of 120 s)
"""

import argparse
import warnings
from pathlib import Path

from drake_uav.diagrams import fly
from drake_uav.io import read_log
from drake_uav.io.realistic_ardupilot import write_ardupilot_log
from drake_uav.io.realistic_px4 import write_px4_log

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("folder", nargs="?", default="out/realistic_autopilot_logs",
                    help="where the logs go")
parser.add_argument("--quick", action="store_true", help="a 40 s flight instead of 120 s")
args = parser.parse_args()
folder = Path(args.folder)
folder.mkdir(parents=True, exist_ok=True)
flight = fly("aerosonde", turbulence="light", seed=3, duration=40.0 if args.quick else 120.0,
             disturbance=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0))
flight.save(folder / "flight.csv")

for writer, name in ((write_ardupilot_log, "flight.bin"), (write_px4_log, "flight.ulg")):
    written = writer(flight, folder / name, seed=3)
    ph = written.phases
    size = written.path.stat().st_size / 1e6
    print(f"{written.path} ({size:.1f} MB): GPS fix {ph.gps_fix_s:.1f} s, armed "
          f"{ph.arm_s:.1f} s, take-off {ph.takeoff_s:.1f} s, flight {ph.flight_s:.1f}"
          f"..{ph.end_s:.1f} s (since boot)")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_log(written.path)
    md = log.metadata
    print(f"  read: {md['firmware']}, MAV_TYPE {md['vehicle_type']['mav_type']}, "
          f"IMU {md['imu_rate_hz']:.0f} Hz, {len(log)} samples, segments {md['segments']}")
    print(f"  modes: {', '.join(f'{mode} at {t:.1f} s' for t, mode in md['flight_modes'])}")
    print(f"  channels: {' '.join(log.measured_names)}")
    for warning in caught:
        print(f"  warning: {warning.message}")
