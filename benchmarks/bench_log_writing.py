"""Writing realistic autopilot logs: the two writers against saving the same arrays.

Flies a 20 s identification flight once, tiles it to ``--seconds`` (default 120) and writes
it with :func:`drake_uav.io.realistic_ardupilot.write_ardupilot_log` (DataFlash ``.bin``)
and :func:`drake_uav.io.realistic_px4.write_px4_log` (ULog ``.ulg``), best of ``--repeat``
runs in wall time. Peer, measured in the same run: ``numpy.savez`` of the flight's
measured channels (the raw cost of putting the same numbers on disk). Printed: seconds
per writer, the file size and the ratio to the peer. Target: a two-minute flight written
in well under a second by each writer.

Run: python benchmarks/bench_log_writing.py [--seconds 120] [--repeat 3]; --quick: a 20 s flight
written once, in seconds.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from timing import best_of

from drake_uav.diagrams import fly
from drake_uav.io import FlightLog
from drake_uav.io.realistic_ardupilot import write_ardupilot_log
from drake_uav.io.realistic_px4 import write_px4_log


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true",
                        help="a 20 s flight written once (seconds)")
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.repeat = 20.0, 1
    flight = fly(duration=20.0, seed=4)
    copies = max(int(np.ceil(args.seconds / 20.0)), 1)
    n = copies * len(flight)
    measured = {k: np.tile(flight[k], copies) for k in flight.measured_names}
    log = FlightLog(np.arange(n) * 0.01, measured, units=flight.units, metadata=flight.metadata)
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        peer = best_of(args.repeat, lambda: np.savez(out / "peer.npz", **measured))[1]
        print(f"{n * 0.01:.0f} s flight, {len(measured)} channels; peer numpy.savez "
              f"{peer:.3f} s")
        for name, writer in (("ArduPilot .bin", write_ardupilot_log), ("PX4 .ulg", write_px4_log)):
            target = out / writer.__name__
            target.mkdir()
            seconds = best_of(args.repeat, lambda w=writer, t=target: w(log, t / "log", seed=0))[1]
            size = sum(p.stat().st_size for p in target.rglob("*") if p.is_file()) / 1e6
            print(f"{name:15s} {seconds:.3f} s  {size:.1f} MB  {seconds / peer:.1f} x the peer")


if __name__ == "__main__":
    main()
