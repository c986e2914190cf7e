"""Reading long autopilot logs: the library's readers against pymavlink and pyulog.

Writes two logs of a ``--minutes`` (default 30) flight with the library's own writers
(:mod:`drake_uav.io.writers`) and times the readers on them, best of ``--repeat`` runs,
in wall time and in CPU time of this process (``time.process_time``):

* an ArduPlane 4.x DataFlash ``.bin``: two IMUs (``IMU`` with ``I`` 0 and 1) at ``--rate``
  (400 Hz), ATT 25 Hz, RCOU 50 Hz, GPS 5 Hz, ARSP and BARO 10 Hz, XKF2 (two cores) 25 Hz,
  the SERVOn_* parameters, the firmware message and a flight mode, read by
  :func:`drake_uav.io.ardupilot.read_ardupilot`. Peer: pymavlink's message-by-message
  parsing, the usual way to read a ``.bin`` in Python (``DFReader_binary`` and a
  ``recv_match(type="IMU")`` loop keeping the IMU fields), timed on the first
  ``--peer-messages`` IMU messages and extrapolated to the file's IMU count (the index
  pass of ``DFReader_binary``'s constructor is timed once, in full);
* a PX4 1.14 ULog ``.ulg``: sensor_combined at ``--rate``, vehicle_attitude 50 Hz,
  actuator_servos and actuator_motors 50 Hz, actuator_outputs, vehicle_local_position,
  airspeed, vehicle_air_data 10 Hz, vehicle_gps_position 5 Hz, vehicle_status 1 Hz, with
  the field layouts and parameters of :mod:`drake_uav.io.realistic_px4`, read by
  :func:`drake_uav.io.px4.read_px4`. Peer: pyulog's parse alone, ``ULog(path)`` of every
  topic (the reader itself parses through pyulog, only the topics it needs).

Printed: file size, times, samples of the FlightLog, MB/s (file size over the best wall
time), the peers and the ratios, and the load average of the machine before and after
(wall time grows with other load on a shared machine, CPU time much less). Target:
the 30-minute 400 Hz ``.bin`` read in <= 3 s wall time.

The files go into a temporary folder, or into ``--keep DIR`` (kept, and reused by the
next run with the same ``--minutes`` and ``--rate``).

``--quick`` reads a 2-minute log once (pymavlink on 20,000 IMU messages): the same figures,
the target scaled to the log's length.

Run: python benchmarks/bench_log_reading.py [--minutes 30] [--rate 400] [--repeat 3]
     [--peer-messages 200000] [--keep DIR] [--quick]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from figures import figure
from timing import best_of

from drake_uav.io.ardupilot import read_ardupilot
from drake_uav.io.px4 import read_px4
from drake_uav.io.realistic_px4 import _TOPICS as PX4_LAYOUTS  # PX4 1.14 field layouts
from drake_uav.io.realistic_px4 import _parameters as px4_parameters
from drake_uav.io.writers import DataFlashWriter, ULogWriter

TARGET_S = 3.0
START_S = 1.0
"""Time of the first message after boot [s]."""
_BIN_FORMATS = (
    ("IMU", "QBffffffIIfBB", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH"),
    ("ATT", "QccccCCffB", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF"),
    ("RCOU", "QHHHHHHHHHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6,C7,C8,C9,C10,C11,C12,C13,C14"),
    ("GPS", "QBBIHBcLLeffffB", "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw,U"),
    ("ARSP", "QBffcffBBffB", "TimeUS,I,Airspeed,DiffPress,Temp,RawPress,Offset,U,H,Hp,TR,Pri"),
    ("BARO", "QBffcfIffB", "TimeUS,I,Alt,Press,Temp,CRt,SMS,Offset,GndTemp,Health"),
    ("XKF2", "QBccccchhhhhhfff", "TimeUS,C,AX,AY,AZ,VWN,VWE,MN,ME,MD,MX,MY,MZ,IDX,IDY,IS"),
    ("PARM", "QNf", "TimeUS,Name,Value"),
    ("MSG", "QZ", "TimeUS,Message"),
    ("MODE", "QMBB", "TimeUS,Mode,ModeNum,Rsn"),
)
_SERVO_FUNCTIONS = {1: 4, 2: 19, 3: 70, 4: 21}
"""SERVOn_FUNCTION: aileron, elevator, throttle, rudder on outputs 1-4."""
_PX4_RATES = {"vehicle_attitude": 50.0, "actuator_servos": 50.0, "actuator_motors": 50.0,
              "actuator_outputs": 10.0, "vehicle_local_position": 10.0, "airspeed": 10.0,
              "vehicle_air_data": 10.0, "vehicle_gps_position": 5.0, "vehicle_status": 1.0}
"""PX4 topic -> logging rate [Hz] (sensor_combined at ``--rate``)."""


def _times_us(duration: float, rate: float) -> np.ndarray:
    """Message times [us] at ``rate`` [Hz] over ``duration`` [s], from :data:`START_S`."""
    return np.round(1e6 * (START_S + np.arange(int(duration * rate)) / rate)).astype(np.uint64)


def write_bin(path: Path, duration: float, rate: float) -> Path:
    """An ArduPlane-like ``.bin`` of ``duration`` [s] with the IMUs at ``rate`` [Hz]."""
    rng = np.random.default_rng(0)
    w = DataFlashWriter()
    for name, fmt, columns in _BIN_FORMATS:
        w.define(name, fmt, columns)
    w.add("MSG", TimeUS=np.array([10], np.uint64), Message="ArduPlane V4.3.7 (bench)")
    w.add("MODE", TimeUS=np.array([20], np.uint64), Mode=10, ModeNum=10, Rsn=1)
    names = [f"SERVO{n}_{k}" for n in range(1, 15)
             for k in ("FUNCTION", "MIN", "MAX", "TRIM", "REVERSED")]
    values = [v for n in range(1, 15) for v in (_SERVO_FUNCTIONS.get(n, 0), 1100, 1900, 1500, 0)]
    w.add("PARM", TimeUS=np.full(len(names), 5, np.uint64), Name=names,
          Value=np.array(values, float))
    imu = _times_us(duration, rate)
    for instance in (0, 1):
        w.add("IMU", TimeUS=imu, I=instance, GyrX=rng.normal(0.0, 0.1, imu.size),
              GyrY=rng.normal(0.0, 0.1, imu.size), GyrZ=rng.normal(0.0, 0.1, imu.size),
              AccX=rng.normal(0.0, 0.5, imu.size), AccY=rng.normal(0.0, 0.5, imu.size),
              AccZ=rng.normal(-9.8, 0.5, imu.size), T=25.0, GH=1, AH=1)
    att = _times_us(duration, 25.0)
    w.add("ATT", TimeUS=att, Roll=rng.normal(0.0, 10.0, att.size), Pitch=2.0,
          Yaw=(np.arange(att.size) * 0.1) % 360.0)
    for core in (0, 1):
        w.add("XKF2", TimeUS=att, C=core, VWN=1.0, VWE=2.0)
    rcou = _times_us(duration, 50.0)
    w.add("RCOU", TimeUS=rcou, C1=np.round(1500 + 300 * np.sin(np.arange(rcou.size) / 50)),
          C2=1500, C3=1400, C4=1500)
    gps = _times_us(duration, 5.0)
    w.add("GPS", TimeUS=gps, I=0, Status=3, NSats=14, Lat=47.0 + 1e-6 * np.arange(gps.size),
          Lng=8.0, Alt=500.0, Spd=20.0, GCrs=10.0, VZ=0.0)
    slow = _times_us(duration, 10.0)
    w.add("ARSP", TimeUS=slow, I=0, Airspeed=20.0 + rng.normal(0.0, 0.3, slow.size),
          DiffPress=240.0, Temp=25.0, H=1)
    w.add("BARO", TimeUS=slow, I=0, Alt=100.0, Press=95_000.0, Health=1)
    return w.save(path)


def write_ulg(path: Path, duration: float, rate: float) -> Path:
    """A PX4 1.14 ``.ulg`` of ``duration`` [s] with sensor_combined at ``rate`` [Hz]."""
    rng = np.random.default_rng(1)
    w = ULogWriter()
    w.info("sys_name", "PX4")
    w.info("ver_sw_release", 0x010E03FF)
    px4_parameters(w)
    ids = {}
    for topic in ("sensor_combined", *_PX4_RATES):
        w.format(topic, PX4_LAYOUTS[topic])
        ids[topic] = w.subscribe(topic)
    us = _times_us(duration, rate)
    w.data("sensor_combined", ids["sensor_combined"], timestamp=us,
           gyro_rad=rng.normal(0.0, 0.1, (us.size, 3)),
           accelerometer_m_s2=rng.normal([0.0, 0.0, -9.8], 0.5, (us.size, 3)),
           gyro_integral_dt=round(1e6 / rate), accelerometer_integral_dt=round(1e6 / rate))
    us = {topic: _times_us(duration, hz) for topic, hz in _PX4_RATES.items()}
    n = {topic: t.size for topic, t in us.items()}
    yaw = 0.5 * np.arange(n["vehicle_attitude"]) / 50.0
    w.data("vehicle_attitude", ids["vehicle_attitude"], timestamp=us["vehicle_attitude"],
           timestamp_sample=us["vehicle_attitude"],
           q=np.column_stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)]))
    servos = np.full((n["actuator_servos"], 8), np.nan)
    servos[:, :4] = 0.2 * np.sin(np.arange(n["actuator_servos"])[:, None] / 50.0 + np.arange(4))
    motors = np.full((n["actuator_motors"], 12), np.nan)
    motors[:, 0] = 0.6
    for topic, control in (("actuator_servos", servos), ("actuator_motors", motors)):
        w.data(topic, ids[topic], timestamp=us[topic], timestamp_sample=us[topic],
               control=control)
    pwm = np.zeros((n["actuator_outputs"], 16))
    pwm[:, :5] = (1580.0, 1500.0, 1500.0, 1500.0, 1500.0)
    w.data("actuator_outputs", ids["actuator_outputs"], timestamp=us["actuator_outputs"],
           noutputs=8, output=pwm)
    t = us["vehicle_local_position"]
    w.data("vehicle_local_position", ids["vehicle_local_position"], timestamp=t,
           timestamp_sample=t, x=20.0 * (t - t[0]) / 1e6, y=0.0, z=-100.0, vx=20.0, vy=0.0,
           vz=0.0, xy_valid=1, z_valid=1, v_xy_valid=1, v_z_valid=1)
    t = us["airspeed"]
    w.data("airspeed", ids["airspeed"], timestamp=t, timestamp_sample=t,
           indicated_airspeed_m_s=20.0 + rng.normal(0.0, 0.3, t.size),
           true_airspeed_m_s=20.0 + rng.normal(0.0, 0.3, t.size), confidence=1.0)
    t = us["vehicle_air_data"]
    w.data("vehicle_air_data", ids["vehicle_air_data"], timestamp=t, timestamp_sample=t,
           baro_alt_meter=600.0, baro_pressure_pa=94_300.0, rho=1.1)
    t = us["vehicle_gps_position"]
    w.data("vehicle_gps_position", ids["vehicle_gps_position"], timestamp=t,
           timestamp_sample=t, lat=470_000_000, lon=80_000_000, alt=600_000, fix_type=3,
           vel_m_s=20.0, vel_n_m_s=20.0, satellites_used=14)
    t = us["vehicle_status"]
    w.data("vehicle_status", ids["vehicle_status"], timestamp=t, arming_state=2, nav_state=15,
           vehicle_type=2, system_type=1)
    return w.save(path)


def pymavlink_imu(path: Path, messages: int, total: int) -> tuple[float, float, int, float]:
    """pymavlink reading every IMU message (extrapolated): (wall [s], CPU [s], messages
    timed, CPU of the index pass [s]). The constructor's index pass over the file is timed
    once, in full; the ``recv_match`` loop on the first ``messages`` IMU messages, scaled
    to ``total``."""
    from pymavlink.DFReader import DFReader_binary

    wall, cpu = time.perf_counter(), time.process_time()
    reader = DFReader_binary(str(path))
    index = (time.perf_counter() - wall, time.process_time() - cpu)
    rows = []
    wall, cpu = time.perf_counter(), time.process_time()
    while len(rows) < messages:
        m = reader.recv_match(type="IMU")
        if m is None:
            break
        rows.append((m.TimeUS, m.I, m.GyrX, m.GyrY, m.GyrZ, m.AccX, m.AccY, m.AccZ))
    loop = (time.perf_counter() - wall, time.process_time() - cpu)
    scale = total / max(len(rows), 1)
    return index[0] + scale * loop[0], index[1] + scale * loop[1], len(rows), index[1]


def pyulog_parse(path: Path) -> int:
    """pyulog's parse of every topic; returns the number of data messages."""
    from pyulog import ULog

    return sum(len(d.data["timestamp"]) for d in ULog(str(path)).data_list)


def _report(label: str, size: float, samples: int, wall: float, cpu: float) -> None:
    print(f"  {label}: best wall {wall:.2f} s, CPU {cpu:.2f} s; {samples} samples, "
          f"{size / 1e6 / wall:.0f} MB/s")


def _timed_read(path: Path, write, read, kind: str, args) -> tuple[int, float, float]:
    """Writes the log at ``path`` unless it exists, reads it ``args.repeat`` times with
    ``read`` and prints the best; returns (file size [B], best wall [s], its CPU [s])."""
    if not path.exists():
        write(path, 60.0 * args.minutes, args.rate)
    size = path.stat().st_size
    print(f"{kind}: {path.name}, {size / 1e6:.0f} MB")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log, wall, cpu = best_of(args.repeat, lambda: read(path))
    _report(f"{read.__name__} (best of {args.repeat})", size, len(log), wall, cpu)
    return size, wall, cpu


def bench_bin(folder: Path, args) -> None:
    """read_ardupilot on the ``.bin`` against pymavlink."""
    path = folder / f"plane_{args.minutes:g}min_{args.rate:g}hz.bin"
    size, wall, cpu = _timed_read(path, write_bin, read_ardupilot, "ArduPlane .bin", args)
    imu_total = 2 * int(60.0 * args.minutes * args.rate)
    peer_wall, peer_cpu, timed, index = pymavlink_imu(path, args.peer_messages, imu_total)
    print(f"  pymavlink DFReader_binary + recv_match(type='IMU'): {peer_wall:.1f} s wall, "
          f"{peer_cpu:.1f} s CPU for {imu_total} IMU messages (index pass {index:.1f} s CPU; "
          f"loop timed on {timed}, extrapolated); ratio pymavlink / read_ardupilot "
          f"{peer_cpu / cpu:.0f}x (CPU)")
    target = TARGET_S * args.minutes / 30.0  # the target is per 30 minutes of flight
    print(f"  target <= {target:.2g} s wall ({TARGET_S:g} s per 30 min): "
          f"{'met' if wall <= target else 'NOT met'}")
    figure("read_bin_s", wall, "s", "lower")
    figure("read_bin_cpu_s", cpu, "s", "lower")
    figure("read_bin_mb_per_s", size / 1e6 / wall, "MB/s")
    figure("pymavlink_imu_cpu_s", peer_cpu, "s", "lower")
    figure("pymavlink_over_read_bin", peer_cpu / cpu, "ratio")


def bench_ulg(folder: Path, args) -> None:
    """read_px4 on the ``.ulg`` against pyulog's parse."""
    path = folder / f"px4_{args.minutes:g}min_{args.rate:g}hz.ulg"
    size, wall, cpu = _timed_read(path, write_ulg, read_px4, "PX4 .ulg", args)
    messages, peer_wall, peer_cpu = best_of(args.repeat, lambda: pyulog_parse(path))
    print(f"  pyulog ULog(path), every topic: best wall {peer_wall:.2f} s, CPU "
          f"{peer_cpu:.2f} s ({messages} messages); ratio read_px4 / pyulog "
          f"{cpu / peer_cpu:.2f} (CPU)")
    figure("read_ulg_s", wall, "s", "lower")
    figure("read_ulg_cpu_s", cpu, "s", "lower")
    figure("read_ulg_mb_per_s", size / 1e6 / wall, "MB/s")
    figure("pyulog_parse_cpu_s", peer_cpu, "s", "lower")
    figure("read_ulg_over_pyulog", cpu / peer_cpu, "ratio", "lower")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0, help="log duration [min]")
    parser.add_argument("--rate", type=float, default=400.0, help="IMU rate [Hz]")
    parser.add_argument("--repeat", type=int, default=3, help="runs per reader (best kept)")
    parser.add_argument("--peer-messages", type=int, default=200_000,
                        help="IMU messages pymavlink parses before extrapolating")
    parser.add_argument("--keep", type=Path, metavar="DIR",
                        help="write (or reuse) the logs in DIR instead of a temporary folder")
    parser.add_argument("--quick", action="store_true",
                        help="a 2-minute log read once, 20,000 IMU messages for pymavlink")
    args = parser.parse_args()
    if args.quick:
        args.minutes, args.repeat = 2.0, 1
        args.peer_messages = min(args.peer_messages, 20_000)
    load = os.getloadavg()
    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} (1, 5, 15 min) before")
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        bench_bin(folder, args)
        bench_ulg(folder, args)
    load = os.getloadavg()
    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} (1, 5, 15 min) after")


if __name__ == "__main__":
    main()
