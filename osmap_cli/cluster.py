"""Running a batch's jobs as tasks on a Dask cluster (``--scheduler`` / ``--scheduler-file``).

One task per job, sent to Dask's distributed scheduler: an existing cluster (its address, or the
file ``dask-scheduler --scheduler-file`` writes), or ``local:N``, a cluster of N single-threaded
worker processes started here on 127.0.0.1 only and closed at the end. The workers run each
job exactly as ``-j`` does (``Job.run`` through ``records.run_caught``: the same atomic writes,
skip / overwrite rules and records) and write its outputs themselves, so the output folder must
be on a file system the workers share; the records come back here and are reported as they
complete by the caller's reporter (osmap_cli.batch.run_jobs), so lines, --json, the summary and
the exit codes are those of ``-j``.

- Numba threads: every job runs with ``threads`` Numba threads (``numba.set_num_threads`` in
  the task; ``local:N`` workers also start with NUMBA_NUM_THREADS=threads), one by default. The
  bytes do not depend on it.
- One job at a time per worker process (a lock), whatever the worker's thread count: Numba's
  default threading layer must not be entered by two threads at once, and the task changes
  into the client's working folder (relative paths mean what they meant here).
- A worker that dies takes only its task with it: the scheduler runs the task again
  elsewhere; ``local:N`` allows one such failure (LOCAL_SCHEDULER_CONFIG), an existing cluster
  its own ``distributed.scheduler.allowed-failures``. Then the job is reported failed. Tasks are
  submitted with ``retries=1`` for an exception outside the job (the job's own errors are
  records, never retried).
- ``--fail-fast``: after the first failed record a distributed Event is set; every task checks
  it before starting its job and returns "not run" when it is set. Jobs already running finish
  and are reported, as with ``-j``.

distributed is imported only here and only when a batch uses a cluster (``pip install
'osmap[cluster]'``); at import time this module needs only the standard library and
osmap_cli.errors and osmap_cli.records.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import os
import re
import threading
import time
import uuid
from dataclasses import dataclass

from osmap_cli.errors import OsmapError
from osmap_cli.records import failed_record, run_caught

__all__ = ["ClusterSpec", "EXTRA_HINT", "available", "parse_scheduler", "run_cluster",
           "start_local_cluster"]

EXTRA_HINT = "pip install 'osmap[cluster]'"
LOCAL_HOST = "127.0.0.1"
_LOCAL_RE = re.compile(r"local:(\d+)")
# a task's answer when --fail-fast stopped the batch before its job started
_NOT_RUN = "not run"
# The scheduler of local:N: a task whose worker died runs once more, then fails (KilledWorker);
# a worker holds only the task it runs (no queued ones that its death would count against).
LOCAL_SCHEDULER_CONFIG = {"distributed.scheduler.allowed-failures": 1,
                          "distributed.scheduler.worker-saturation": 1.0}


@dataclass(frozen=True)
class ClusterSpec:
    """Where the tasks go: exactly one of ``address``, ``scheduler_file``, ``local`` (N
    workers started here), and the Numba threads per job."""

    address: str | None = None
    scheduler_file: str | None = None
    local: int | None = None
    threads: int = 1

    def describe(self) -> str:
        if self.local is not None:
            return f"local:{self.local}"
        return self.address or f"the scheduler in {self.scheduler_file}"


def available() -> bool:
    """Whether dask.distributed is installed (the ``cluster`` extra)."""
    return importlib.util.find_spec("distributed") is not None


def parse_scheduler(text: str) -> tuple[str | None, int | None]:
    """``--scheduler`` TEXT as (address, None) or (None, N) for ``local:N``; ValueError when
    it is neither."""
    text = text.strip()
    if text.lower().startswith("local"):
        match = _LOCAL_RE.fullmatch(text.lower())
        if match is None or not 1 <= int(match.group(1)) <= 256:
            raise ValueError(f"{text!r}: expected local:N with N workers, 1 to 256 "
                             "(e.g. local:2)")
        return None, int(match.group(1))
    if not text or any(c.isspace() for c in text):
        raise ValueError(f"{text!r}: expected the scheduler's address (tcp://HOST:8786) "
                         "or local:N")
    return text, None


# ---------------------------------------------------------------------------------------------
# the worker side

_JOB_LOCK = threading.Lock()


def _set_numba_threads(threads: int) -> str | None:
    """numba.set_num_threads(THREADS), capped at the worker's NUMBA_NUM_THREADS; returns a
    warning when capped."""
    import numba

    most = numba.config.NUMBA_NUM_THREADS
    numba.set_num_threads(min(threads, most))
    if threads > most:
        return (f"--threads {threads}: this worker has at most {most} Numba threads "
                f"(NUMBA_NUM_THREADS); used {most}")
    return None


def _task(job, cwd: str, threads: int, debug: bool, stop: str | None):
    """Run JOB on a worker: its record (records.run_caught), or _NOT_RUN when the STOP event is
    set (--fail-fast)."""
    with _JOB_LOCK:
        if stop is not None:
            from distributed import Event

            if Event(stop).is_set():
                return _NOT_RUN
        started = time.monotonic()
        try:
            warning = _set_numba_threads(threads)
            before = os.getcwd()
        except Exception as exc:  # noqa: BLE001 - reported as the job's failure
            return failed_record(job, f"worker set-up: {type(exc).__name__}: {exc}",
                                 started, internal=True)
        try:
            os.chdir(cwd)
        except OSError as exc:
            import socket

            return failed_record(job, f"{cwd}: cannot enter the batch's working folder on "
                                 f"worker {socket.gethostname()} ({exc.strerror or exc}); the "
                                 "workers need the same file system at the same paths", started)
        try:
            record = run_caught(job, debug)
        finally:
            with contextlib.suppress(OSError):
                os.chdir(before)
        if warning:
            record.setdefault("_warnings", [])
            record["_warnings"] = [warning, *record["_warnings"]]
        return record


# ---------------------------------------------------------------------------------------------
# the client side


@contextlib.contextmanager
def _client(spec: ClusterSpec):
    """A distributed Client for SPEC; a local cluster is started here and closed after."""
    from distributed import Client

    if spec.local is not None:
        try:
            cluster = start_local_cluster(spec.local, spec.threads)
        except Exception as exc:  # noqa: BLE001
            raise OsmapError(f"cannot start a local Dask cluster: {type(exc).__name__}: "
                             f"{exc}") from None
        try:
            with Client(cluster) as client:
                yield client
        finally:
            cluster.close()
        return
    try:
        if spec.scheduler_file is not None:
            client = Client(scheduler_file=spec.scheduler_file)
        else:
            client = Client(spec.address)
    except (OSError, TimeoutError, ValueError) as exc:
        raise OsmapError(f"cannot connect to the Dask scheduler ({spec.describe()}): "
                         f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
    with client:
        yield client


def start_local_cluster(workers: int, threads: int = 1):
    """The cluster of ``local:N``: a distributed.LocalCluster of WORKERS single-threaded worker
    processes (NUMBA_NUM_THREADS=THREADS), everything on 127.0.0.1 and no dashboard, with
    LOCAL_SCHEDULER_CONFIG. The caller closes it."""
    import logging

    import dask
    from distributed import LocalCluster

    with dask.config.set(LOCAL_SCHEDULER_CONFIG):
        return LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, host=LOCAL_HOST,
            dashboard_address=None, worker_dashboard_address=None,
            # the scheduler's HTTP routes (health checks) on a free loopback port
            scheduler_kwargs={"dashboard": False, "dashboard_address": f"{LOCAL_HOST}:0"},
            silence_logs=logging.ERROR,
            env={"NUMBA_NUM_THREADS": str(threads), "OPENBLAS_NUM_THREADS": "1",
                 "MKL_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"},
        )


def _lost(job, exc: BaseException, started: float) -> dict:
    """The failed record of a task that raised (a worker that died too often, ...)."""
    name = type(exc).__name__
    if name == "KilledWorker":
        text = ("the worker running it died, and again on the retry (Dask KilledWorker); "
                "the job may need more memory than a worker has")
    else:
        text = f"on the cluster: {name}: {exc}"
    return failed_record(job, text, started, internal=True)


def run_cluster(jobs: list, spec: ClusterSpec, fail_fast: bool, debug: bool, report) -> int:
    """Run JOBS as tasks on SPEC's cluster; REPORT each record as its task completes. Returns
    how many jobs were not run (--fail-fast)."""
    from distributed import Event, as_completed

    cwd = os.getcwd()
    token = uuid.uuid4().hex[:12]
    if spec.local is not None and spec.local > len(jobs):  # no idle workers to start
        spec = dataclasses.replace(spec, local=len(jobs))
    # the worker has no terminal: no progress bars there
    jobs = [dataclasses.replace(job, progress=False) if getattr(job, "progress", False)
            else job for job in jobs]
    not_run = 0
    with _client(spec) as client:
        stop_name = f"osmap-stop-{token}" if fail_fast else None
        stop = Event(stop_name, client=client) if fail_fast else None
        started = time.monotonic()
        futures = {}
        for position, job in enumerate(jobs):
            future = client.submit(_task, job, cwd, spec.threads, debug, stop_name,
                                   key=f"osmap-{token}-{position}", pure=False, retries=1)
            futures[future] = job
        try:
            for future in as_completed(list(futures)):
                job = futures[future]
                try:
                    record = future.result()
                except Exception as exc:  # noqa: BLE001 - one lost task must not stop the batch
                    record = _lost(job, exc, started)
                future.release()
                if record == _NOT_RUN:
                    not_run += 1
                    continue
                report(record)
                if stop is not None and record["status"] == "failed" and not stop.is_set():
                    stop.set()
        except BaseException:
            client.cancel(list(futures))
            raise
        finally:
            if stop is not None:
                with contextlib.suppress(Exception):
                    stop.clear()
    return not_run
