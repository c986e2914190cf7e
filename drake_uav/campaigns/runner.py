"""Runs a campaign on Dask (or in this process) and streams its rows to Parquet.

:func:`run_campaign` expands the campaign into runs, skips the runs whose rows
are already on disk (a resumed campaign), submits the others and writes each
finished row as it arrives (:class:`~drake_uav.campaigns.results.ResultsStore`).
A run that raises gives an error row; the campaign goes on.

Where the runs go:

* ``workers=None`` (default): a Dask ``LocalCluster`` with one worker process
  per core, one thread per worker (numerical libraries single-threaded, so the
  rows do not depend on how many runs share a core), Dask settings
  :data:`LOCAL_CLUSTER_CONFIG`;
* ``workers=N``: a ``LocalCluster`` of N workers;
* ``scheduler="tcp://host:8786"``: an existing Dask cluster;
* ``workers=0``: every run in this process, one after the other (no Dask).

The rows are the same, bit for bit, whatever the workers and the order in
which the runs finish: each run depends only on its seed and parameters, and
the merged file is sorted by (point, seed). Only ``wall_time_s`` differs.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TextIO

import pyarrow as pa

import drake_uav
from drake_uav.campaigns.definition import Campaign, RunSpec
from drake_uav.campaigns.progress import ProgressBar
from drake_uav.campaigns.registry import check_scenario
from drake_uav.campaigns.registry import scenario as resolve_scenario
from drake_uav.campaigns.results import METRIC, PARAM, ResultsStore

__all__ = ["CampaignRun", "run_campaign", "execute_run", "local_cluster"]

_METRIC_KINDS = (bool, int, float, str, type(None))


@dataclasses.dataclass(frozen=True)
class CampaignRun:
    """What :func:`run_campaign` did."""

    path: Path
    """The merged Parquet file."""
    table: pa.Table
    """Every row of the campaign (sorted by point, seed)."""
    ran: int
    """Runs done in this session."""
    resumed: int
    """Runs found on disk and not run again."""
    errors: int
    """Error rows in the whole campaign."""


def _checked_metrics(metrics: Any) -> dict[str, Any]:
    if not isinstance(metrics, Mapping):
        raise TypeError(f"the scenario returned {type(metrics).__name__}, not a dict of metrics")
    out = {}
    for name, value in metrics.items():
        if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
            value = value.item()  # numpy scalar
        if not isinstance(value, _METRIC_KINDS):
            raise TypeError(f"metric {name!r}: {type(value).__name__} is not a bool, int, "
                            f"float or str")
        out[METRIC + str(name)] = value
    return out


def execute_run(scenario, run: RunSpec, version: str) -> dict[str, Any]:
    """Runs one scenario run and returns its row (an error row if it raises)."""
    start = time.perf_counter()
    row = {"point": run.point, "seed": run.seed, "version": version,
           **{PARAM + k: v for k, v in run.params.items()}}
    try:
        metrics = _checked_metrics(resolve_scenario(scenario)(run.seed, dict(run.params)))
        row.update(status="ok", error=None, **metrics)
    except Exception as err:  # a failed run is a row, never a lost campaign
        row.update(status="error", error=f"{type(err).__name__}: {err}")
    row["wall_time_s"] = time.perf_counter() - start
    return row


def _scenario_problem(scenario) -> str | None:
    """Why ``scenario`` cannot be loaded where the runs run, or None. Returned, not raised, so
    that the worker logs nothing: the caller reports it in one line."""
    try:
        resolve_scenario(scenario)
    except ValueError as err:
        return str(err)
    return None


def _error_row(run: RunSpec, version: str, err: BaseException) -> dict[str, Any]:
    return {"point": run.point, "seed": run.seed, "version": version, "status": "error",
            "error": f"{type(err).__name__}: {err}", "wall_time_s": float("nan"),
            **{PARAM + k: v for k, v in run.params.items()}}


def _run_local(pending, scenario, version, store, bar, rows, flush_every) -> None:
    for i, run in enumerate(pending, 1):
        row = execute_run(scenario, run, version)
        _finish(row, store, bar, rows, flush=i % flush_every == 0)


def _finish(row, store, bar, rows, flush: bool) -> None:
    rows.append(row)
    store.add(row)
    if flush:
        store.flush()
    bar.update(error=row["status"] != "ok")


LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.scheduler.worker-saturation": 1.0,
}
"""Dask settings of the LocalCluster that :func:`run_campaign` starts. Its dashboard is off,
so the workers' statistical profiler (a stack sample of the running task every 10 ms,
taken on the worker's event loop while the task waits for the interpreter lock) only costs
time; the event-loop tick (every 20 ms), memory (100 ms) and system (500 ms) monitors wake
less often; the workers allocate memory as any Python process does (Dask's
``MALLOC_TRIM_THRESHOLD_`` would turn off glibc's adaptive mmap threshold, so every large
array is mapped and unmapped again); and a worker is sent its next run only when it is
free, so no run waits behind another while a worker idles at the end."""


def _local_cluster(workers: int):
    """A Dask LocalCluster of ``workers`` one-thread processes with
    :data:`LOCAL_CLUSTER_CONFIG` and no dashboard."""
    import dask
    from dask.distributed import LocalCluster

    with dask.config.set(LOCAL_CLUSTER_CONFIG):
        # Dask's own log lines below ERROR (a run cancelled by Ctrl-C, a worker stopped
        # on shutdown) are not the user's business: the command prints one line.
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                            dashboard_address=None, scheduler_kwargs={"dashboard": False},
                            silence_logs=logging.ERROR)


@contextlib.contextmanager
def local_cluster(workers: int):
    """The scheduler address of a local Dask cluster of ``workers`` processes (as
    :func:`run_campaign` starts), closed on exit; ``None`` when ``workers`` is 0 (run in
    this process). Benchmarks that run several campaigns share one cluster this way.

    Parameters
    ----------
    workers : int
        Worker processes (one thread each); 0 for none.

    Yields
    ------
    str or None
        The scheduler's address, for ``run_campaign(..., scheduler=)``.
    """
    if workers == 0:
        yield None
        return
    with _local_cluster(workers) as cluster:
        yield cluster.scheduler_address


def _client(workers: int | None, scheduler: str | None):
    from dask.distributed import Client

    if scheduler is not None:
        return Client(scheduler), None
    cluster = _local_cluster(os.cpu_count() or 1 if workers is None else workers)
    return Client(cluster), cluster


def _run_dask(pending, scenario, version, store, bar, rows, flush_every, workers, scheduler):
    from dask.distributed import as_completed

    client, cluster = _client(workers, scheduler)
    try:
        # One worker loads the scenario (its modules, as the runs do on every worker; this
        # process needs none of them): one that does not load there raises here, before
        # any row is written.
        problem = client.submit(_scenario_problem, scenario, pure=False).result()
        if problem is not None:
            raise ValueError(f"{problem} (on the Dask workers)")
        futures = {client.submit(execute_run, scenario, run, version, pure=False): run
                   for run in pending}
        for i, future in enumerate(as_completed(futures), 1):
            try:
                row = future.result()
            except Exception as err:  # the worker died (KilledWorker) or could not unpickle
                row = _error_row(futures[future], version, err)
            _finish(row, store, bar, rows, flush=i % flush_every == 0)
            future.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_campaign(campaign: Campaign, out: str | os.PathLike, *, workers: int | None = None,
                 scheduler: str | None = None, progress: bool | TextIO = True,
                 flush_every: int = 1) -> CampaignRun:
    """Runs ``campaign`` and writes its rows to the Parquet file ``out``.

    Args:
        campaign: the scenario, parameters and seeds.
        out: the results file; if it (or its ``.parts`` folder of an interrupted
            run) holds rows of the same campaign, only the missing runs are run.
        workers: Dask workers of a new ``LocalCluster`` (default: one per core);
            0 runs everything in this process.
        scheduler: address of an existing Dask scheduler (``workers`` is then unused).
        progress: a progress bar on stderr (True), on a given stream, or none (False).
        flush_every: finished rows per part file (1: nothing finished is lost when
            the campaign is interrupted).

    Raises:
        ValueError: the scenario is unknown or not a scenario function (checked before any
            run; a built-in name without loading it); ``out`` holds rows of another campaign
            definition, or is a file that is not campaign results
            (:class:`~drake_uav.reporting.output.OutputRefusedError`, nothing is written).
    """
    if flush_every < 1:
        raise ValueError(f"flush_every must be >= 1, got {flush_every}")
    check_scenario(campaign.scenario)
    store = ResultsStore(out, campaign.definition())
    rows = store.load()
    done = {(r["point"], r["seed"]) for r in rows}
    pending = [run for run in campaign.runs() if run.key not in done]
    stream = (sys.stderr if progress is True else None) if isinstance(progress, bool) else progress
    bar = ProgressBar(len(pending), done=len(done), stream=stream)
    scenario = campaign.scenario
    version = drake_uav.__version__
    try:
        if not pending or workers == 0 and scheduler is None:
            resolve_scenario(scenario)  # an unknown name fails here, not in every run
            _run_local(pending, scenario, version, store, bar, rows, flush_every)
        else:
            _run_dask(pending, scenario, version, store, bar, rows, flush_every, workers,
                      scheduler)
    finally:
        store.flush()
        bar.close()
    table = store.merge(rows)
    errors = sum(r["status"] != "ok" for r in rows)
    return CampaignRun(store.path, table, len(pending), len(done), errors)
