"""What a log's native rates can support (identification.assessment.logged_rates): the rules,
and the main job on the bundled sample thinned to a 10 Hz IMU and 3 Hz commands, as a
ground-station CSV export and as a MAVLink telemetry log, against the same at its own
100 Hz."""

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import drake_uav
from drake_uav.cli import main
from drake_uav.identification import identify
from drake_uav.identification.assessment.logged_rates import (
    BAND,
    TIMING,
    RateNeed,
    analysis_band,
    interpolated_rate,
    logged_rates,
)
from drake_uav.identification.statistics.residuals import diagnose
from drake_uav.io import read_log
from drake_uav.io.flight_log import FlightLog
from drake_uav.io.grouped_csv_writer import write_grouped_csv
from drake_uav.io.tlog_writer import write_tlog
from drake_uav.reporting.explanations import residual_meaning
from drake_uav.reporting.figures import spectral_density_plot
from drake_uav.reporting.identification_report import write_report
from drake_uav.vehicles.fixed_wing import aerosonde

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"
COMMANDS = ("cmd_elevator", "cmd_aileron", "cmd_rudder", "cmd_throttle")
IMU_GROUP = ("imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r", "att_roll", "att_pitch",
             "att_yaw", "pitot_qbar", "pitot_airspeed", "vane_alpha", "vane_beta", "baro_alt")
GPS = ("gps_pn", "gps_pe", "gps_pd", "gps_vn", "gps_ve", "gps_vd")
# Everything that needs the commands, the gyros or the IMU at more than these rates.
UNSUPPORTED = {"command_time_skew", "actuator_time_delay", "thrust_propwash",
               "control_nonlinearity", "control_cross_coupling", "rate_coupling",
               "unsteady_alphadot", "accelerometer_lever_arm", "CL_q", "CL_elevator", "CD_q",
               "CD_elevator", "CY_p", "CY_r", "CY_aileron", "CY_rudder", "Cl_p", "Cl_r",
               "Cl_aileron", "Cl_rudder", "Cm_q", "Cm_elevator", "Cn_p", "Cn_r", "Cn_aileron",
               "Cn_rudder"}


def _log(rate_hz: float, seconds: float = 4.0, streams: dict | None = None) -> FlightLog:
    t = np.arange(0.0, seconds, 1.0 / rate_hz)
    return FlightLog(t, {"imu_p": np.sin(t), "cmd_aileron": np.cos(t)},
                     units={"imu_p": "rad/s", "cmd_aileron": "rad"},
                     metadata={} if streams is None else {"streams": streams})


def test_the_needed_rates_follow_from_the_isolation_band_and_the_grid():
    # The cubic Savitzky-Golay smoothing of 0.2 s on the 50 Hz grid: -3 dB at 4.9 Hz.
    band = analysis_band(50.0)
    assert band == pytest.approx(4.94, abs=0.01)
    # Linear interpolation's gain sinc^2(f_b / f_s) is 1/sqrt(2) at f_s = 15.5 Hz.
    assert np.sinc(band / interpolated_rate(band)) ** 2 == pytest.approx(1 / math.sqrt(2))
    rates = logged_rates(_log(10.0))
    assert rates.needed_rate("imu_p", BAND)[0] == pytest.approx(15.47, abs=0.01)
    assert rates.needed_rate("cmd_aileron", BAND)[0] == 50.0      # held: once per grid step
    assert rates.needed_rate("imu_p", TIMING)[0] == 50.0          # a time: one grid step
    assert rates.nyquist(["imu_p", "cmd_aileron"]) == pytest.approx(5.0)


def test_a_term_is_judged_on_its_slowest_channel_and_a_full_rate_log_supports_all():
    need = RateNeed("actuator_time_delay", "time delay", ("imu_p", "cmd_aileron"), TIMING)
    slow = logged_rates(_log(10.0, streams={"SERVO": {"rate_hz": 3.0,
                                                      "channels": ["cmd_aileron"]}}))
    limit = slow.limit(need)
    assert (limit.term, limit.channel, limit.kind) == ("actuator_time_delay", "cmd_aileron",
                                                       TIMING)
    assert limit.native_rate_hz == 3.0 and limit.needed_rate_hz == 50.0
    assert "not identifiable at the logged rates: cmd_aileron logged at 3 Hz, needs 50 Hz" \
        in limit.message()
    # The gyro at 10 Hz carries no damping derivative either (15.5 Hz).
    assert slow.limit(RateNeed("Cl_p", "damping", ("imu_p",))).channel == "imu_p"
    assert slow.limit(RateNeed("x", "x", ("not_logged",))) is None
    fast = logged_rates(_log(100.0))
    assert fast.limits([need, RateNeed("Cl_p", "damping", ("imu_p",))]) == ()
    # 50 Hz commands are exactly what the 50 Hz grid needs.
    assert logged_rates(_log(50.0)).limit(need) is None
    with pytest.raises(ValueError, match="RateNeed.kind"):
        RateNeed("x", "x", ("imu_p",), "fast")
    with pytest.raises(ValueError, match="grid_rate_hz"):
        logged_rates(_log(10.0), 0.0)


def test_the_native_rate_is_the_stream_s_not_the_grid_s():
    rates = logged_rates(_log(10.0, streams={"SERVO": {"rate_hz": 3.0,
                                                       "channels": ["cmd_aileron"]}}))
    assert rates.rates["cmd_aileron"] == 3.0
    assert rates.rates["imu_p"] == pytest.approx(10.0)  # not in a stream: the log's rate


def test_no_spectral_peak_is_named_above_the_native_nyquist_frequency():
    class Diagnosis:  # a residual that is not white, with a peak at 2 Hz and one at 12 Hz
        is_white, integrated_time, sample_rate, drift_significant = False, 50.0, 50.0, False
        spectral_peaks = [type("Peak", (), {"frequency": f}) for f in (12.0, 2.0)]

    full, = residual_meaning({"Cl": Diagnosis()}, 0.05)
    thinned, = residual_meaning({"Cl": Diagnosis()}, 0.05, nyquist_hz=5.0)
    assert "12 Hz, 2 Hz" in full
    assert "spectral peak at 2 Hz" in thinned and "12 Hz" not in thinned


def test_the_residual_spectrum_is_drawn_up_to_the_native_nyquist_frequency_only():
    rng = np.random.default_rng(3)
    t = np.arange(3000) / 50.0
    diagnosis = diagnose(rng.normal(size=t.size) + np.sin(2 * np.pi * 12.0 * t), 50.0)
    full = spectral_density_plot({"Cl": diagnosis})
    thinned = spectral_density_plot({"Cl": diagnosis}, nyquist_hz=5.0)
    top = [max(line.get_xdata().max() for line in fig.axes[0].get_lines())
           for fig in (full, thinned)]
    assert top[0] == pytest.approx(25.0) and top[1] <= 5.0
    marked = [float(t.get_text().split()[0]) for t in full.axes[0].texts]
    assert len(marked) == 1 and marked[0] == pytest.approx(12.0, abs=0.2)
    assert not thinned.axes[0].texts  # the 12 Hz peak is not marked


@pytest.fixture(scope="module")
def sample():
    return read_log(SAMPLE)


def _thinned(sample, kind: str, folder: Path) -> Path:
    """The bundled flight with a 10 Hz IMU, 3 Hz commands and 5 Hz GPS."""
    if kind == "tlog":
        return write_tlog(sample, folder / "low.tlog", rates={
            "imu": 10, "attitude": 10, "commands": 3, "air": 10, "position": 5})
    return write_grouped_csv(sample, folder / "low.csv", {
        "imu": (10.0, IMU_GROUP), "cmd": (3.0, COMMANDS), "gps": (5.0, GPS)})


@pytest.mark.parametrize("kind", ["csv", "tlog"])
def test_a_10_hz_imu_and_3_hz_commands_claim_nothing_and_name_what_they_cannot_support(
        sample, kind, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the reader's low-rate IMU warning
        log = read_log(_thinned(sample, kind, tmp_path))
        run = identify(log, aerosonde())
    # Before: command_time_skew, actuator_time_delay (CD, Cl) and thrust_propwash at twice
    # its size, all from the held 3 Hz commands.
    assert run.findings == ()
    assert run.discovery.message.startswith("the model is incomplete")
    assert {r.term for r in run.rate_limits} == UNSUPPORTED
    limits = {r.term: r for r in run.rate_limits}
    assert limits["actuator_time_delay"].native_rate_hz == pytest.approx(3.0, rel=1e-3)
    assert limits["actuator_time_delay"].needed_rate_hz == 50.0
    assert limits["Cl_p"].channel == "imu_p"
    assert limits["Cl_p"].native_rate_hz == pytest.approx(10.0, rel=1e-3)
    assert limits["Cl_p"].needed_rate_hz == pytest.approx(15.47, abs=0.01)
    skew = run.compatibility["command_time_skew"]
    assert not skew.applied and skew.note.startswith("command_time_skew (time skew): not "
                                                     "identifiable at the logged rates")
    tested = {e.effect for r in run.discovery.rounds for e in r}
    assert not tested & UNSUPPORTED
    products = [n.removeprefix("data_driven:").split("*") for n in tested
                if n.startswith("data_driven:")]
    assert products and all(set(p) <= {"alpha", "beta"} for p in products)
    # The derivatives it cannot support are not fitted: the model keeps the catalog's.
    # Fitted, they took whatever the slowed channels gave (a positive roll damping, Cl_p =
    # +0.048, and a roll reconstruction off by 143 deg/s).
    catalog = aerosonde().derivatives
    fixed = {n: v for terms in run.discovery.fixed.values() for n, v in terms.items()}
    assert fixed == {n: catalog[n] for n in UNSUPPORTED if n in catalog}
    assert not any(set(fit.names) & UNSUPPORTED for fit in run.discovery.final.values())
    assert not [w for w in run.derivative_warnings if set(w.derivatives) & UNSUPPORTED]
    summary = run.summary()
    assert summary["parameters"]["Cl"]["Cl_p"] == {
        "estimate": catalog["Cl_p"], "sigma": None, "significant": False, "fixed": True,
        "catalog": catalog["Cl_p"]}
    mae = summary["reconstruction_mae_holdout"]
    print(f"{kind}: reconstruction MAE p {math.degrees(mae['p']['after']):.1f} deg/s, "
          f"q {math.degrees(mae['q']['after']):.1f} deg/s, "
          f"r {math.degrees(mae['r']['after']):.1f} deg/s")
    assert math.degrees(mae["p"]["after"]) < 20.0
    assert summary["reconstruction_divergences"]["after"] == 0
    if kind == "tlog":  # the report and summary.json list them under their own heading
        folder = write_report(run, tmp_path / "report")
        report = (folder / "report.md").read_text()
        assert "## Not identifiable at the logged rates" in report
        assert "| actuator_time_delay | time delay | cmd_elevator | 3 | 50 |" in report
        assert re.search(r"\| Cl_p \| - \| -0\.26 \| [^\n]* \| fixed: not at the logged "
                         r"rates \|", report)
        listed = json.loads((folder / "summary.json").read_text())[
            "not_identifiable_at_logged_rates"]
        assert {r["term"] for r in listed} == UNSUPPORTED


def test_at_its_own_rates_the_bundled_sample_still_finds_the_propwash_alone(tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["identify", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["findings"] == ["thrust_propwash"]
    assert summary["not_identifiable_at_logged_rates"] == []
    report = (out / "report.md").read_text()
    assert "Not identifiable at the logged rates" not in report
    capsys.readouterr()
