"""Meshcat replay of flight logs: the track read from a log, the scene, the static page in a
headless browser without network."""

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from pydrake.geometry import Meshcat

import drake_uav
from drake_uav.cli import main
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.reporting.replay import export_replay_html, replay, replay_track

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"
CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(n)), None)
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="no headless Chromium (Debian: apt-get install -y chromium)")


@pytest.fixture(scope="module")
def meshcat():
    return Meshcat()


@pytest.fixture(scope="module")
def fixed_wing() -> FlightLog:
    """30 s of the bundled flight: measured GPS position and attitude only."""
    return FlightLog.load(SAMPLE).slice(0.0, 30.0)


@pytest.fixture(scope="module")
def hexacopter() -> FlightLog:
    """A hexacopter circling, motor 2 failing at 4 s, with a reference and an unsafe disc."""
    t = np.linspace(0.0, 10.0, 201)
    circle = {"pn": 2 * np.sin(t / 3), "pe": 2 * np.cos(t / 3) - 2, "pd": -3 + 0.1 * t}
    health = {f"motor_health_{i}": np.where((i == 2) & (t > 4), 0.0, 1.0) for i in range(6)}
    reference = {"ref_pn": circle["pn"], "ref_pe": circle["pe"], "ref_pd": np.full_like(t, -3)}
    return FlightLog(
        t, measured={**health, **reference},
        truth={**circle, "roll": 0.1 * np.sin(t), "pitch": 0 * t, "yaw": t / 5},
        units={**{k: "1" for k in health}, **{k: "m" for k in [*circle, *reference]},
               "roll": "rad", "pitch": "rad", "yaw": "rad"},
        metadata={"vehicle": "multirotor", "unsafe_disc": {"center": [-1.0, -1.0],
                                                           "radius": 1.5}})


def test_track_of_a_fixed_wing_log(fixed_wing):
    track = replay_track(fixed_wing)
    assert track.kind == "fixed_wing" and track.motor_health is None
    np.testing.assert_array_equal(track.position[:, 0], fixed_wing["gps_pn"])
    assert track.rotation.shape == (len(fixed_wing), 3, 3)


def test_track_of_a_multirotor_log(hexacopter):
    track = replay_track(hexacopter)
    assert track.kind == "multirotor" and track.motor_health.shape == (201, 6)
    assert track.unsafe_disc == (-1.0, -1.0, 1.5) and track.reference.shape == (201, 3)


def test_failed_motors_from_metadata():
    t = np.linspace(0.0, 2.0, 21)
    log = FlightLog(t, truth={"pn": t, "pe": 0 * t, "pd": -t},
                    units={"pn": "m", "pe": "m", "pd": "m"},
                    metadata={"num_motors": 4, "failed_motors": [1], "failure_time": 1.0})
    health = replay_track(log).motor_health
    assert health[:, 1].tolist() == [1.0] * 10 + [0.0] * 11 and health[:, [0, 2, 3]].all()


def test_bad_logs_are_named():
    t = np.linspace(0.0, 1.0, 5)
    with pytest.raises(FlightLogError, match="no position"):
        replay_track(FlightLog(t, measured={"imu_p": 0 * t}, units={"imu_p": "rad/s"}))
    log = FlightLog(t, truth={"pn": t, "pe": t, "pd": t}, units=dict.fromkeys(("pn", "pe", "pd"),
                                                                               "m"),
                    metadata={"unsafe_disc": {"radius": 2.0}})
    with pytest.raises(FlightLogError, match="unsafe_disc"):
        replay_track(log)


def test_scene_objects_and_failed_motor_twins(meshcat, hexacopter):
    scene = replay(hexacopter, meshcat)
    # body, 6 arms, 6 healthy + 6 failed motors, trail, reference, unsafe disc
    assert len(scene.objects) == 22 and scene.frames == 251
    assert all(meshcat.HasPath(path) for path in scene.objects)
    wing = replay(replay_track(FlightLog.load(SAMPLE).slice(0.0, 5.0)), meshcat)
    assert len(wing.objects) == 5 and not meshcat.HasPath("/replay/vehicle/motor_0")


def test_static_page_is_self_contained(tmp_path, fixed_wing):
    page = export_replay_html(fixed_wing, tmp_path / "replay.html").read_text()
    # No tag loads anything from elsewhere (the browser test below runs without network).
    assert not re.findall(r"<(?:script|link|img|iframe)\b[^>]*\b(?:src|href)=", page)
    assert page.count('fetch("data:') >= 3  # scene and animation embedded as data URLs


_PROBE = """<script>
function probe(tries) {
  var root = viewer.scene.getObjectByName("replay"), n = 0;
  if (root) root.traverse(function (o) { if (o.isMesh || o.isLine) n += 1; });
  if (n == 0 && tries > 0) { setTimeout(function () { probe(tries - 1); }, 250); return; }
  var out = document.createElement("pre");
  out.id = "probe";
  out.textContent = "objects=" + n;
  document.body.appendChild(out);
}
setTimeout(function () { probe(80); }, 500);
</script>
</body>"""


def _chromium(page: Path, profile: Path, *args: str) -> str:
    """Runs headless Chromium on ``page`` without any network; returns stdout."""
    done = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
         "--disable-background-networking", "--disable-component-update", "--no-first-run",
         f"--user-data-dir={profile}", "--proxy-server=127.0.0.1:9",
         "--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=20000",
         "--window-size=800,600", *args, page.as_uri()],
        capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@needs_chromium
@pytest.mark.parametrize("vehicle", ["fixed_wing", "hexacopter"])
def test_static_page_shows_the_vehicle_in_headless_chromium(tmp_path, request, vehicle):
    log = request.getfixturevalue(vehicle)
    path = tmp_path / "replay.html"
    scene = replay(log)
    path.write_text(scene.meshcat.StaticHtml())
    # The scene as the browser built it: every object drawn, and nothing else under /replay.
    probe = tmp_path / "probe.html"
    html = path.read_text()
    cut = html.rindex("</body>")
    probe.write_text(html[:cut] + _PROBE + html[cut + len("</body>"):])
    dom = _chromium(probe, tmp_path / "profile1", "--dump-dom")
    assert f'<pre id="probe">objects={len(scene.objects)}</pre>' in dom
    # The picture: a drawn canvas (not a blank page) with the vehicle's orange in it.
    shot = tmp_path / "shot.png"
    _chromium(path, tmp_path / "profile2", f"--screenshot={shot}")
    rgb = np.asarray(Image.open(shot).convert("RGB"), float) / 255.0
    r, g, b = np.moveaxis(rgb, -1, 0)
    # Orange to red (VEHICLE_COLOR shaded, failed motors): no other object has this hue (the
    # translucent unsafe disc over the grey ground has too much blue).
    vehicle_pixels = int(np.sum((r > 0.25) & (r > 1.5 * g) & (r > 2.5 * b)))
    print(f"\n{vehicle}: {len(scene.objects)} objects, {vehicle_pixels} vehicle pixels, "
          f"image std {rgb.std():.3f}")
    assert rgb.std() > 0.02
    assert vehicle_pixels >= 10


def test_command_line_replay(tmp_path, hexacopter):
    log = hexacopter.save(tmp_path / "hexa.parquet")
    assert main(["replay", str(log)]) == 0
    assert (tmp_path / "hexa.html").stat().st_size > 100_000
    assert main(["replay", str(tmp_path / "missing.csv")]) == 2
