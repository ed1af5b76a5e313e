"""Running jobs: one at a time or in worker processes, each reported as it finishes.

A job is one unit of a batch (one exemplar -> its outputs). Every job type subclasses
:class:`Job` and has the same shape, run by :meth:`Job.run`: ``read`` its inputs, ``check``
them against the outputs it will write, ``compute``, ``stage`` every output in one output
transaction (osmap_cli.output), which is then committed, all or nothing. :func:`run_jobs` runs a
list of jobs, in this process (``-j 1``), in ``-j N`` spawned worker processes or as tasks on a
Dask cluster (osmap_cli.cluster, ``--scheduler``), reports each finished job's record
(osmap_cli.records: one line, or one JSON object with ``--json``), and returns the exit code: 0
when no job failed, 1 otherwise. A job's bytes do not depend on how it was run.

This module knows nothing of the command line: errors are OsmapError, output goes to
stdout / stderr as plain lines.
"""

from __future__ import annotations

import json
import os
import sys
import time

from osmap_cli.errors import OsmapError
from osmap_cli.records import failed_record, job_record, run_caught

__all__ = ["Job", "run_jobs", "skip_or_refuse"]


class Job:
    """The shape every job has. A subclass is a frozen dataclass with at least the fields
    ``exemplar`` (names the job), ``replace`` (False: an existing output makes the job
    "skipped"), ``refused`` (why it must not run, or None) and ``progress``, and implements
    ``outputs``, ``describe``, ``read``, ``check``, ``compute`` and ``stage``."""

    @property
    def outputs(self) -> list[str]:
        """Every file the job writes."""
        raise NotImplementedError

    def describe(self) -> dict:
        """The JSON record's job fields (input, outputs, size, seed, options)."""
        raise NotImplementedError

    def read(self):
        """Read the inputs (raises OsmapError naming the file)."""
        raise NotImplementedError

    def check(self, inputs) -> None:
        """Everything that can be checked before the work (formats, channels, memory)."""

    def compute(self, inputs):
        """The synthesis itself."""
        raise NotImplementedError

    def stage(self, outputs, inputs, result) -> tuple[str, list[str]]:
        """Stage every output in OUTPUTS (an osmap_cli.output.Outputs); returns the summary
        line and any warnings."""
        raise NotImplementedError

    # Jobs of this kind may compute two at a time in threads of one process (run_jobs, -j 1):
    # their kernels release the GIL and may run in two threads at once, and two of them fit in
    # memory side by side. A subclass decides per job.
    overlaps = False

    def prepare(self):
        """read -> check -> compute: (inputs, result), nothing written yet."""
        inputs = self.read()
        self.check(inputs)
        return inputs, self.compute(inputs)

    def execute(self, ahead=None) -> tuple[str, list[str]]:
        """read -> check -> compute -> stage -> commit; returns the summary line and warnings.
        Raises OsmapError for a bad input or output (then nothing is written). AHEAD: this
        job's prepare() run earlier in another thread (see _Ahead), or None."""
        from osmap_cli.output import Outputs

        prepared = None if ahead is None else ahead.result()
        inputs, result = self.prepare() if prepared is None else prepared
        with Outputs() as outputs:
            line, warnings = self.stage(outputs, inputs, result)
            outputs.commit()
        return line, warnings

    def run(self, ahead=None) -> dict:
        """execute() unless the job is skipped or refused; returns the job's record (status
        "ok" or "skipped"). Raises OsmapError for a bad input or output."""
        started = time.monotonic() if ahead is None else ahead.started
        skipped = skip_or_refuse(self, started)
        if skipped is not None:
            return skipped
        line, warnings = self.execute(ahead)
        record = job_record(self, "ok", started)
        record["_line"] = f"{line} ({record['seconds']:.1f} s)"
        record["_warnings"] = warnings
        return record


def skip_or_refuse(job, started: float) -> dict | None:
    """The "skipped" record when an output exists and the job may not replace it; raises
    OsmapError when the job is refused; None when it may run."""
    if not job.replace:
        existing = [p for p in job.outputs if os.path.lexists(p)]
        if existing:
            return job_record(job, "skipped", started,
                              reason=f"{existing[0]} exists (--overwrite replaces it)")
    if job.refused:
        raise OsmapError(job.refused)
    return None


# ---------------------------------------------------------------------------------------------
# running many jobs


def _init_worker(threads: int) -> None:
    # before Numba is imported in this process; a value the user set wins
    os.environ.setdefault("NUMBA_NUM_THREADS", str(threads))
    for variable in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(variable, "1")


def _worker_job(job, debug: bool) -> dict:
    try:
        return run_caught(job, debug)
    except KeyboardInterrupt:
        return failed_record(job, "interrupted", time.monotonic())


def _say(line: str, err: bool = False) -> None:
    print(line, file=sys.stderr if err else sys.stdout, flush=err)


class _Reporter:
    """Prints one finished job: a line (or a JSON object) and counts the outcomes."""

    def __init__(self, json_lines: bool, quiet: bool, debug: bool):
        self.json_lines, self.quiet, self.debug = json_lines, quiet, debug
        self.counts = {"ok": 0, "skipped": 0, "failed": 0}

    def __call__(self, record: dict) -> None:
        status = record["status"]
        self.counts[status] += 1
        if status == "failed":
            if record.get("_traceback"):
                _say(record["_traceback"].rstrip(), err=True)
            kind = "internal error" if record.get("_internal") else "error"
            _say(f"osmap: {kind}: {record['error']}", err=True)
        elif status == "skipped" and not self.quiet:
            _say(f"osmap: skipped {record['input']}: {record['reason']}", err=True)
        if not self.quiet:
            for warning in record.get("_warnings", ()):
                _say(f"osmap: warning: {warning}", err=True)
        if self.json_lines:
            public = {k: v for k, v in record.items() if not k.startswith("_")}
            _say(json.dumps(public, sort_keys=False))
        elif status == "ok" and not self.quiet:
            _say(record["_line"])
        sys.stdout.flush()


def run_jobs(jobs: list, workers: int = 1, fail_fast: bool = False,
             json_lines: bool = False, quiet: bool = False, debug: bool = False,
             cluster=None) -> int:
    """Run the jobs and report each one; returns 0 when none failed, else 1.

    A single job (``osmap synth X -o Y``) raises its error instead, so that it is reported
    exactly like any other command failure. CLUSTER (an osmap_cli.cluster.ClusterSpec) runs
    every job, even a single one, as a task on a Dask cluster instead (``workers`` is then 1).
    """
    report = _Reporter(json_lines, quiet, debug)
    started = time.monotonic()
    if len(jobs) == 1 and not json_lines and cluster is None:
        report(jobs[0].run())
        return 0
    not_run = 0
    if cluster is not None:
        from osmap_cli.cluster import run_cluster

        not_run = run_cluster(jobs, cluster, fail_fast, debug, report)
    elif workers <= 1 or len(jobs) == 1:
        not_run = _run_in_turn(jobs, fail_fast, debug, report)
    else:
        not_run = _run_pool(jobs, workers, fail_fast, debug, report)
    failed = report.counts["failed"]
    if len(jobs) > 1 and not quiet:
        parts = [f"{report.counts['ok']} written", f"{report.counts['skipped']} skipped",
                 f"{failed} failed"]
        if not_run:
            parts.append(f"{not_run} not run (--fail-fast)")
        _say(f"osmap: {len(jobs)} jobs: {', '.join(parts)} "
             f"({time.monotonic() - started:.1f} s)", err=True)
    return 1 if failed else 0


def _run_in_turn(jobs: list, fail_fast: bool, debug: bool, report) -> int:
    """Run the jobs in this process, committing and reporting them in order; returns how many
    were not run (--fail-fast). When every job overlaps (Job.overlaps) and there are two cores,
    two jobs compute at a time (_Ahead): one job's single-threaded stages use the core that
    the other's row bands leave free. Each job computes the same bytes either way."""
    ahead = None
    if len(jobs) > 1 and (os.cpu_count() or 1) > 1 and all(job.overlaps for job in jobs):
        ahead = _Ahead(jobs)
    try:
        for position, job in enumerate(jobs):
            record = run_caught(job, debug, None if ahead is None else ahead.take(position))
            report(record)
            if fail_fast and record["status"] == "failed":
                return len(jobs) - position - 1
    except BaseException:
        if ahead is not None:
            ahead.close(wait=False)
        ahead = None
        raise
    finally:
        if ahead is not None:
            ahead.close(wait=True)
    return 0


class _Ahead:
    """The jobs' prepare() (read, check, compute) on THREADS threads of this process, started
    in order and at most DEPTH jobs past the one the caller takes last (held results bound the
    memory); the caller takes each job's outcome in order and stages and commits it itself."""

    def __init__(self, jobs: list, threads: int = 2, depth: int = 2):
        import threading

        self._jobs, self._depth = jobs, depth
        self._cond = threading.Condition()
        self._next = 0  # the next job to start
        self._limit = depth  # jobs below this index may start
        self._done: dict = {}  # index -> _Prepared
        self._closed = False
        self._threads = [threading.Thread(target=self._work, name="osmap-job", daemon=True)
                         for _ in range(threads)]
        for thread in self._threads:
            thread.start()

    def _work(self) -> None:
        while True:
            with self._cond:
                while not self._closed and self._next >= min(self._limit, len(self._jobs)):
                    self._cond.wait()
                if self._closed:
                    return
                index = self._next
                self._next += 1
            prepared = _Prepared(self._jobs[index])
            with self._cond:
                self._done[index] = prepared
                self._cond.notify_all()

    def take(self, index: int) -> _Prepared:
        """Job INDEX's outcome (waits for it); lets the jobs DEPTH past it start."""
        with self._cond:
            self._limit = max(self._limit, index + 1 + self._depth)
            self._cond.notify_all()
            while index not in self._done:
                self._cond.wait()
            return self._done.pop(index)

    def close(self, wait: bool) -> None:
        """Start no more jobs; WAIT: for those running to end (their outcomes are dropped)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if wait:
            for thread in self._threads:
                thread.join()


class _Prepared:
    """One job's prepare() run now (in an _Ahead thread): its time of start and its outcome,
    None when the job is to be skipped or refused (Job.run decides that again)."""

    def __init__(self, job):
        self.started = time.monotonic()
        self._outcome, self._error = None, None
        try:
            if not job.refused and skip_or_refuse(job, self.started) is None:
                self._outcome = job.prepare()
        except BaseException as exc:  # noqa: BLE001 - raised again in the caller's thread
            self._error = exc

    def result(self):
        """(inputs, result) of job.prepare(), None if it did not run; raises its error."""
        if self._error is not None:
            raise self._error
        return self._outcome


def _run_pool(jobs: list, workers: int, fail_fast: bool, debug: bool, report) -> int:
    """Run jobs in `workers` spawned processes; returns how many were cancelled."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    workers = min(workers, len(jobs))
    threads = max(1, (os.cpu_count() or 1) // workers)
    context = multiprocessing.get_context("spawn")
    not_run = 0
    with ProcessPoolExecutor(max_workers=workers, mp_context=context,
                             initializer=_init_worker, initargs=(threads,)) as pool:
        pending = {pool.submit(_worker_job, job, debug) for job in jobs}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in sorted(done, key=lambda f: id(f)):
                    record = future.result()
                    report(record)
                    if fail_fast and record["status"] == "failed" and pending:
                        cancelled = [f for f in pending if f.cancel()]
                        not_run += len(cancelled)
                        pending -= set(cancelled)
        except BaseException:
            for future in pending:
                future.cancel()
            raise
    return not_run
