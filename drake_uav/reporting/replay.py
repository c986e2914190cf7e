"""3-D replay of a flight log in Meshcat, live or as one self-contained HTML file.

:func:`replay_track` reads what a replay needs from a
:class:`~drake_uav.io.flight_log.FlightLog`; :func:`replay` draws it in a
Meshcat (``pydrake.geometry.StartMeshcat()`` for a live viewer) with an
animation; :func:`export_replay_html` writes ``Meshcat.StaticHtml()``, a page
that plays the flight without a server or network.

What is drawn (paths under ``/replay``):

===================  ========================================================
path                 content
===================  ========================================================
``vehicle/...``      simple meshes: fuselage, wing and tails of a fixed wing;
                     body, arms and one motor per rotor of a multirotor (a
                     failed motor turns red while it is failed)
``trail``            the flown path
``reference``        the reference path, when the log has one
``unsafe_disc``      the unsafe disc on the ground, when the log names one
===================  ========================================================

Log channels and metadata read (first found wins):

* position [m, NED]: truth ``pn, pe, pd``, or measured ``gps_pn, gps_pe, gps_pd``;
* attitude: truth ``qw, qx, qy, qz``, or ``roll, pitch, yaw``, or measured
  ``att_roll, att_pitch, att_yaw`` [rad]; level when none;
* reference [m, NED]: ``ref_pn, ref_pe, ref_pd``;
* motor health: ``motor_health_0`` ... ``motor_health_<n-1>`` (1 healthy, 0 failed;
  below 0.5 is drawn as failed), or metadata ``failed_motors`` (indices) with
  ``failure_time`` [s] (default: from the start);
* vehicle: metadata ``vehicle`` ("fixed_wing" or "multirotor"), else a multirotor
  when the log has motor health or metadata ``num_motors``, else a fixed wing;
  ``num_motors`` (default 4 or the health channels);
* unsafe disc: metadata ``unsafe_disc = {"center": [n, e], "radius": r}`` [m], on
  the ground (d = 0).

Display frame: Meshcat's z is up, so NED positions and FRD bodies are shown
rotated by pi about the north axis (x north, y west, z up). The view is centred on
the flight's start; the vehicle is drawn larger than life on long flights so that
it stays visible (``vehicle_scale``).
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Cylinder, Meshcat, MeshcatAnimation, Rgba
from pydrake.math import RigidTransform, RotationMatrix

from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.model.rotations import euler_to_rotmat, quat_to_rotmat
from drake_uav.reporting.output import (
    REPLAY_MARKER,
    check_output_file,
    is_replay_page,
    replace_file,
)

__all__ = ["ReplayTrack", "ReplayScene", "replay_track", "replay", "export_replay_html"]

ROOT = "/replay"
_FLIP = np.diag([1.0, -1.0, -1.0])  # NED -> north, west, up (and FRD -> FLU)
VEHICLE_COLOR = Rgba(1.0, 0.45, 0.0, 1.0)
"""The vehicle's colour (orange): a screenshot finds the vehicle by it."""
_HEALTHY = Rgba(0.1, 0.7, 0.2, 1.0)
_FAILED = Rgba(0.9, 0.0, 0.0, 1.0)


@dataclasses.dataclass(frozen=True)
class ReplayTrack:
    """What a replay draws, in NED (module docstring)."""

    time: np.ndarray
    """Sample times [s] (N)."""
    position: np.ndarray
    """Positions, NED [m] (N, 3)."""
    rotation: np.ndarray
    """Body (FRD) to NED rotation matrices (N, 3, 3)."""
    kind: str
    """"fixed_wing" or "multirotor"."""
    reference: np.ndarray | None = None
    """Reference positions, NED [m] (N, 3)."""
    motor_health: np.ndarray | None = None
    """(N, n) motor health, 1 healthy, 0 failed (multirotor)."""
    unsafe_disc: tuple[float, float, float] | None = None
    """(north, east, radius) [m] of the unsafe disc on the ground."""


def _first(log: FlightLog, *groups: tuple[str, ...]) -> tuple[str, ...] | None:
    for names in groups:
        if all(n in log for n in names):
            return names
    return None


def _rotations(log: FlightLog) -> np.ndarray:
    quat = _first(log, ("qw", "qx", "qy", "qz"))
    if quat is not None:
        return np.array([quat_to_rotmat(q) for q in log.stack(quat)])
    euler = _first(log, ("roll", "pitch", "yaw"), ("att_roll", "att_pitch", "att_yaw"))
    if euler is not None:
        return np.array([euler_to_rotmat(e) for e in log.stack(euler)])
    return np.broadcast_to(np.eye(3), (len(log), 3, 3)).copy()


def _motor_health(log: FlightLog, kind: str) -> np.ndarray | None:
    names = []
    while f"motor_health_{len(names)}" in log:
        names.append(f"motor_health_{len(names)}")
    if names:
        return log.stack(names)
    if kind != "multirotor":
        return None
    health = np.ones((len(log), int(log.metadata.get("num_motors", 4))))
    failed = [int(i) for i in log.metadata.get("failed_motors", [])]
    if failed:
        after = log.time >= float(log.metadata.get("failure_time", log.time[0]))
        health[np.ix_(after, failed)] = 0.0
    return health


def replay_track(log: FlightLog) -> ReplayTrack:
    """The replay of ``log`` (channels and metadata of the module docstring).

    Raises :class:`FlightLogError` when the log has no position channels.
    """
    position = _first(log, ("pn", "pe", "pd"), ("gps_pn", "gps_pe", "gps_pd"))
    if position is None:
        raise FlightLogError("replay: the log has no position (pn, pe, pd or gps_pn, gps_pe, "
                             "gps_pd)")
    meta = log.metadata
    has_motors = "motor_health_0" in log or "num_motors" in meta or "failed_motors" in meta
    kind = str(meta.get("vehicle", "multirotor" if has_motors else "fixed_wing"))
    if kind not in ("fixed_wing", "multirotor"):
        raise FlightLogError(f"replay: metadata vehicle {kind!r} is not fixed_wing or multirotor")
    reference = _first(log, ("ref_pn", "ref_pe", "ref_pd"))
    disc = meta.get("unsafe_disc")
    if disc is not None:
        try:
            disc = (float(disc["center"][0]), float(disc["center"][1]), float(disc["radius"]))
        except (KeyError, IndexError, TypeError, ValueError):
            raise FlightLogError(f"replay: metadata unsafe_disc must be "
                                 f"{{'center': [n, e], 'radius': r}}, got {disc!r}") from None
    return ReplayTrack(
        time=np.asarray(log.time), position=log.stack(position), rotation=_rotations(log),
        kind=kind, reference=None if reference is None else log.stack(reference),
        motor_health=_motor_health(log, kind), unsafe_disc=disc)


@dataclasses.dataclass(frozen=True)
class ReplayScene:
    """What :func:`replay` drew: the Meshcat, the object paths, the animation's frames."""

    meshcat: Meshcat
    objects: tuple[str, ...]
    """Paths of every geometry drawn (failed-motor twins included)."""
    frames: int


def _fixed_wing(meshcat: Meshcat, path: str, s: float) -> list[str]:
    parts = {  # name: (size x, y, z (FLU) [m], centre)
        "fuselage": ((1.6, 0.18, 0.18), (0.0, 0.0, 0.0)),
        "wing": ((0.3, 2.8, 0.04), (0.1, 0.0, 0.05)),
        "tailplane": ((0.2, 0.9, 0.03), (-0.7, 0.0, 0.05)),
        "fin": ((0.22, 0.03, 0.35), (-0.7, 0.0, 0.22)),
    }
    out = []
    for name, (size, centre) in parts.items():
        meshcat.SetObject(f"{path}/{name}", Box(*(s * np.array(size))), VEHICLE_COLOR)
        meshcat.SetTransform(f"{path}/{name}", RigidTransform(s * np.array(centre)))
        out.append(f"{path}/{name}")
    return out


def _multirotor(meshcat: Meshcat, path: str, s: float, n: int) -> list[str]:
    meshcat.SetObject(f"{path}/body", Box(0.3 * s, 0.3 * s, 0.1 * s), VEHICLE_COLOR)
    out = [f"{path}/body"]
    for i in range(n):
        azimuth = 2.0 * math.pi * (i + 0.5) / n
        direction = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
        arm = f"{path}/arm_{i}"
        meshcat.SetObject(arm, Box(0.5 * s, 0.04 * s, 0.03 * s), VEHICLE_COLOR)
        meshcat.SetTransform(arm, RigidTransform(RotationMatrix.MakeZRotation(azimuth),
                                                 0.25 * s * direction))
        out.append(arm)
        for state, color in (("healthy", _HEALTHY), ("failed", _FAILED)):
            motor = f"{path}/motor_{i}/{state}"
            meshcat.SetObject(motor, Cylinder(0.12 * s, 0.04 * s), color)
            out.append(motor)
        meshcat.SetTransform(f"{path}/motor_{i}", RigidTransform(0.5 * s * direction +
                                                                 [0.0, 0.0, 0.05 * s]))
        meshcat.SetProperty(f"{path}/motor_{i}/failed", "visible", False)
    return out


def _display(position: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """NED [m] (N, 3) -> Meshcat display coordinates (N, 3), relative to ``origin``."""
    return (np.asarray(position) - origin) @ _FLIP


def _sample_indices(time: np.ndarray, fps: float, speed: float) -> np.ndarray:
    frames = int(math.floor((time[-1] - time[0]) / speed * fps)) + 1
    t = time[0] + np.arange(frames) * speed / fps
    return np.clip(np.searchsorted(time, t), 0, time.size - 1)


def _animate(track: ReplayTrack, origin: np.ndarray, fps: float, speed: float,
             motors: int) -> MeshcatAnimation:
    animation = MeshcatAnimation(fps)
    index = _sample_indices(track.time, fps, speed)
    shown = _display(track.position[index], origin)
    failed_before = None
    for frame, k in enumerate(index):
        rotation = RotationMatrix(_FLIP @ track.rotation[k] @ _FLIP)
        animation.SetTransform(frame, f"{ROOT}/vehicle", RigidTransform(rotation, shown[frame]))
        if motors:
            failed = track.motor_health[k] < 0.5
            if failed_before is None or np.any(failed != failed_before):
                for i in range(motors):
                    path = f"{ROOT}/vehicle/motor_{i}"
                    animation.SetProperty(frame, f"{path}/failed", "visible", bool(failed[i]))
                    animation.SetProperty(frame, f"{path}/healthy", "visible",
                                          not bool(failed[i]))
            failed_before = failed
    return animation


def replay(log: FlightLog | ReplayTrack, meshcat: Meshcat | None = None, *, fps: float = 25.0,
           speed: float = 1.0, vehicle_scale: float | None = None) -> ReplayScene:
    """Draws the flight in ``meshcat`` (default: a new ``Meshcat``) and sets its animation.

    Args:
        log: a flight log (read with :func:`replay_track`) or a track.
        meshcat: e.g. ``pydrake.geometry.StartMeshcat()`` for a live viewer.
        fps: animation frames per second of replay.
        speed: replay speed (2: twice as fast as flown).
        vehicle_scale: size factor of the vehicle meshes (default: 1, or larger on
            flights longer than 50 m so that the vehicle stays visible).
    """
    track = log if isinstance(log, ReplayTrack) else replay_track(log)
    if fps <= 0.0 or speed <= 0.0:
        raise ValueError(f"replay: fps and speed must be > 0, got {fps}, {speed}")
    meshcat = meshcat or Meshcat()
    meshcat.Delete(ROOT)
    meshcat.SetProperty("/Axes", "visible", False)  # at the start point: the trail shows it
    origin = np.array([track.position[0, 0], track.position[0, 1], 0.0])
    shown = _display(track.position, origin)
    extent = float(np.ptp(shown, axis=0).max())
    scale = vehicle_scale or max(1.0, extent / 50.0)
    objects = []
    if track.kind == "fixed_wing":
        objects += _fixed_wing(meshcat, f"{ROOT}/vehicle", scale)
        motors = 0
    else:
        motors = track.motor_health.shape[1]
        objects += _multirotor(meshcat, f"{ROOT}/vehicle", scale, motors)
    meshcat.SetLine(f"{ROOT}/trail", shown.T, 2.0, Rgba(0.1, 0.3, 0.9, 1.0))
    objects.append(f"{ROOT}/trail")
    if track.reference is not None:
        meshcat.SetLine(f"{ROOT}/reference", _display(track.reference, origin).T, 2.0,
                        Rgba(0.2, 0.7, 0.2, 1.0))
        objects.append(f"{ROOT}/reference")
    if track.unsafe_disc is not None:
        n, e, radius = track.unsafe_disc
        meshcat.SetObject(f"{ROOT}/unsafe_disc", Cylinder(radius, 0.02 * scale),
                          Rgba(0.85, 0.15, 0.45, 0.35))  # crimson: not the vehicle hue
        meshcat.SetTransform(f"{ROOT}/unsafe_disc",
                             RigidTransform(_display(np.array([[n, e, 0.0]]), origin)[0]))
        objects.append(f"{ROOT}/unsafe_disc")
    centre = 0.5 * (shown.min(axis=0) + shown.max(axis=0))
    distance = max(1.2 * extent, 8.0 * scale)
    meshcat.SetCamera(Meshcat.PerspectiveCamera(fov=50.0, near=0.01 * distance,
                                                far=10.0 * distance))
    meshcat.SetCameraPose(centre + distance * np.array([-0.6, -0.6, 0.5]), centre)
    animation = _animate(track, origin, fps, speed, motors)
    meshcat.SetAnimation(animation)
    return ReplayScene(meshcat, tuple(objects), len(_sample_indices(track.time, fps, speed)))


def export_replay_html(log: FlightLog | ReplayTrack, path: str | os.PathLike,
                       **options) -> Path:
    """Writes the replay of ``log`` as one self-contained HTML page (no server, no network).

    ``options`` go to :func:`replay`. Returns the file's path. An existing ``path`` is
    replaced only if it is an earlier replay page
    (:func:`~drake_uav.reporting.output.is_replay_page`); the page is
    written under a temporary name and renamed, so it appears complete or not at all.

    Raises
    ------
    OutputRefusedError
        ``path`` is a folder or a file that is not a replay page (it is left as it was).
    """
    check_output_file(path, ours=is_replay_page, what="replay page")
    scene = replay(log, **options)
    page = scene.meshcat.StaticHtml()
    doctype, newline, rest = page.partition("\n")
    text = f"{doctype}{newline}{REPLAY_MARKER}\n{rest}"
    return replace_file(lambda tmp: tmp.write_text(text, encoding="utf-8"), path,
                        ours=is_replay_page, what="replay page")
