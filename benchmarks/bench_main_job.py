"""Main-job benchmark: ``drake-uav identify`` on the bundled sample flight, stage by stage.

Run: python benchmarks/bench_main_job.py [--repeats 3] [--log LOG] [--quick]   (quick: one run)

Every run is a fresh interpreter (imports included), as the command line runs it; it
times each stage in wall time and in CPU time of its process (``time.process_time``):

* import: the modules the ``identify`` command imports;
* read: the log (``read_log``);
* isolation: airborne spans, air data, coefficients (``select_samples``);
* discovery: baseline fits, candidate scoring of every round, final fits (``discover``);
* reconstruction: the output-error runs before and after;
* Monte-Carlo: the uncertainty of the measured coefficients;
* report: figures, markdown, HTML and summary.json (``write_report``).

The stages are timed by the job's own progress messages, so the job is the unmodified
:func:`~drake_uav.identification.pipeline.identify`. The best (lowest) of ``--repeats`` runs
is kept per stage and for the whole job. The load average of the machine is printed next to
the figures: on a loaded machine wall time grows with the load, CPU time much less.

The peer: the same candidate regressions done directly with ``numpy.linalg.lstsq`` (ordinary
least squares, no errors-in-variables correction, no statistics): for every candidate of
every discovery round, the blocked K-fold fits and the fit on all the training samples. The
ratio of the discovery stage to that time is what the corrections and the bookkeeping cost.
Target: the whole job <= 5 s wall time on the 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from figures import figure

TARGET_S = 5.0
STAGES = ("import", "read", "isolation", "discovery", "reconstruction", "monte_carlo",
          "report")
#: Progress message prefix -> the stage it starts.
_MESSAGES = {"isolating": "isolation", "discovery round 1": "discovery",
             "reconstructing": "reconstruction", "Monte-Carlo": "monte_carlo"}


class _Clock:
    """Wall and CPU time at marks, by stage name."""

    def __init__(self):
        self.marks = [("start", time.perf_counter(), time.process_time())]

    def mark(self, stage: str) -> None:
        self.marks.append((stage, time.perf_counter(), time.process_time()))

    def stages(self) -> dict[str, tuple[float, float]]:
        """Stage -> (wall, cpu) [s] from its mark to the next one."""
        out = {}
        for (_, w0, c0), (stage, w1, c1) in zip(self.marks[:-1], self.marks[1:], strict=True):
            out[stage] = (w1 - w0, c1 - c0)
        return out


def child(log: str, out_dir: str) -> dict:
    """One run of the job in this (fresh) process; returns the stage times and the run."""
    clock = _Clock()
    from drake_uav.identification.pipeline import identify
    from drake_uav.io.readers import read_log
    from drake_uav.reporting.identification_report import write_report
    from drake_uav.vehicles.loading import load_fixed_wing

    params = load_fixed_wing("aerosonde")
    clock.mark("import")
    data = read_log(log)
    pending = ["read"]

    def progress(message: str) -> None:
        for prefix, stage in _MESSAGES.items():
            if message.startswith(prefix):
                clock.mark(pending[0])
                pending[0] = stage

    run = identify(data, params, progress=progress, source=log)
    clock.mark(pending[0])
    write_report(run, out_dir)
    clock.mark("report")
    stages = clock.stages()
    if set(stages) != set(STAGES):
        raise RuntimeError(f"stages {sorted(stages)}: the job's progress messages changed")
    designs, joint = _peer_designs(run)
    return {"stages": stages, "message": run.discovery.message,
            "peer": peer_times(designs), "candidates": len(designs), "joint": joint}


def peer_times(designs, repeats: int = 3) -> float:
    """Best time [s] of the direct numpy least squares of the candidates' ``designs``."""
    import numpy as np

    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for X, z, edges in designs:
            for a, b in zip(edges[:-1], edges[1:], strict=True):
                keep = np.r_[0:a, b:len(z)]
                theta = np.linalg.lstsq(X[keep], z[keep], rcond=None)[0]
                r = z[a:b] - X[a:b] @ theta
                float(r @ r)
            np.linalg.lstsq(X, z, rcond=None)
        best = min(best, time.perf_counter() - start)
    return float(best)


def _peer_designs(run) -> tuple[list, int]:
    """(X, z, fold edges) of every per-coefficient candidate the run scored: its
    coefficient's design in that round with the candidate's columns added; and how many
    joint (vector-effect) candidates were scored besides, which have no such design."""
    import numpy as np

    from drake_uav.identification.discovery.coefficient_design import baseline_names
    from drake_uav.identification.discovery.effects import effect_library, product_candidates
    from drake_uav.identification.discovery.result import EvidenceRule
    from drake_uav.model.coefficients import regressor_matrix

    rule, samples, params = EvidenceRule(), run.samples, run.params
    n_train = int(round(len(samples) * (1.0 - rule.holdout_fraction)))
    train = samples.subset(slice(0, n_train))
    edges = np.linspace(0, n_train, rule.folds + 1).astype(int)
    effects = {e.name: e for e in effect_library()}

    def columns(effect: str, k: str) -> dict:
        aligned = train.aligned(k)
        if effect in effects:
            return effects[effect].columns(aligned, params, k)
        return {"*".join(key): v for key, v in product_candidates(aligned, params).items()}

    base = {}
    for k in run.discovery.baseline:
        names = baseline_names(params, k)
        base[k] = regressor_matrix(names, train.aligned(k).condition, params.b, params.c)
    out, joint = [], 0
    for evidence in run.discovery.rounds:
        for e in evidence:
            c = columns(e.effect, e.coefficient)
            if not all(n in c for n in e.columns):  # a vector effect's joint parameters
                joint += 1
                continue
            X = np.column_stack([base[e.coefficient], *(c[n] for n in e.columns)])
            out.append((X, np.asarray(train.coefficients[e.coefficient]), edges))
        winners = [e for e in evidence if e.passed and e.effect == evidence[0].effect]
        for e in winners:
            c = columns(e.effect, e.coefficient)
            base[e.coefficient] = np.column_stack([base[e.coefficient],
                                                   *(c[n] for n in e.columns)])
    return out, joint


def _run_child(log: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        command = [sys.executable, __file__, "--child", "--log", log,
                   "--out", str(Path(tmp) / "report")]
        done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the job failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _command_time(log: str | None) -> tuple[float, float]:
    """Wall and CPU time [s] of the ``drake-uav identify`` command itself."""
    with tempfile.TemporaryDirectory() as tmp:
        args = ["identify", "--out", str(Path(tmp) / "report")] + ([log] if log else [])
        command = [sys.executable, "-c", "import sys; from drake_uav.cli import main; "
                   "sys.exit(main(sys.argv[1:]))", *args]
        before = os.times()
        start = time.perf_counter()
        # In the temporary folder: the current folder must not shadow PYTHONPATH.
        subprocess.run(command, capture_output=True, check=True, cwd=tmp)
        wall = time.perf_counter() - start
        after = os.times()
    return wall, (after.children_user - before.children_user
                  + after.children_system - before.children_system)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--log", help="flight log (default: the bundled sample flight)")
    parser.add_argument("--quick", action="store_true", help="one run of each")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.quick:
        args.repeats = 1
    sample = Path(__file__).resolve().parents[1] / "drake_uav" / "data" / "sample_flight.parquet"
    log = args.log or str(sample)
    if args.child:
        print(json.dumps(child(log, args.out)))
        return

    load = os.getloadavg()
    runs = [_run_child(log) for _ in range(args.repeats)]
    commands = [_command_time(args.log) for _ in range(args.repeats)]
    load_after = os.getloadavg()
    print(f"main job on {Path(log).name}, best of {args.repeats} fresh processes; "
          f"{os.cpu_count()} CPUs, load average {load[0]:.1f} before, {load_after[0]:.1f} after")
    print(f"result: {runs[0]['message']}")
    print(f"{'stage':<16}{'wall [s]':>10}{'CPU [s]':>10}")
    for stage in STAGES:
        wall = min(r["stages"][stage][0] for r in runs)
        cpu = min(r["stages"][stage][1] for r in runs)
        print(f"{stage:<16}{wall:>10.3f}{cpu:>10.3f}")
    totals = [(sum(w for w, _ in r["stages"].values()), sum(c for _, c in r["stages"].values()))
              for r in runs]
    wall, cpu = min(t[0] for t in totals), min(t[1] for t in totals)
    print(f"{'whole job':<16}{wall:>10.3f}{cpu:>10.3f}   (target <= {TARGET_S:g} s wall)")
    command_wall = min(c[0] for c in commands)
    command_cpu = min(c[1] for c in commands)
    print(f"{'drake-uav identify':<16}{command_wall:>8.3f}{command_cpu:>10.3f}   "
          "(the command, interpreter start-up included)")
    discovery = min(r["stages"]["discovery"][0] for r in runs)
    peer = min(r["peer"] for r in runs)
    print(f"peer: {runs[0]['candidates']} candidates by numpy lstsq, {peer:.3f} s wall; "
          f"discovery / peer = {discovery / peer:.2f} (the discovery also scored "
          f"{runs[0]['joint']} joint vector-effect candidates, not in the peer)")
    figure("main_job_wall", wall, "s", "lower")
    figure("main_job_cpu", cpu, "s", "lower")
    figure("identify_command_wall", command_wall, "s", "lower")
    for stage in STAGES:
        figure(f"main_job_{stage}_cpu", min(r["stages"][stage][1] for r in runs), "s", "lower")
    figure("discovery_over_numpy_peer", discovery / peer, "x", "lower")


if __name__ == "__main__":
    main()
