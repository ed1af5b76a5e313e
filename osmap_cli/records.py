"""A finished job's record: what every runner (this process, ``-j N`` workers, a Dask cluster)
reports for one job, the same whichever ran it.

    record = run_caught(job)    # {"input", "outputs", ..., "seconds", "status": "ok"}

A record holds the job's ``describe()`` fields, ``seconds`` and ``status`` ("ok", "skipped" or
"failed", then with "error"), and private keys (``_line``, ``_warnings``, ``_internal``,
``_traceback``) that the reporter prints and --json leaves out. This module knows only the job's
shape (``describe``, ``run``, ``exemplar``), not who runs it.
"""

from __future__ import annotations

import time

from osmap_cli.errors import OsmapError

__all__ = ["failed_record", "job_record", "run_caught"]


def job_record(job, status: str, started: float, **more) -> dict:
    """A finished job's record: the job's `describe()` fields, seconds, status and MORE."""
    record = {**job.describe(), "seconds": round(time.monotonic() - started, 3),
              "status": status}
    record.update(more)
    return record


def failed_record(job, message: str, started: float, internal: bool = False) -> dict:
    """The "failed" record of JOB: MESSAGE on one line, naming the job's exemplar; INTERNAL
    marks an unexpected error (reported as "internal error")."""
    text = " ".join(str(message).split())
    if job.exemplar not in text:
        text = f"{job.exemplar}: {text}"
    record = job_record(job, "failed", started, error=text)
    record["_internal"] = internal
    return record


def run_caught(job, debug: bool = False, ahead=None) -> dict:
    """job.run(), with every failure turned into a "failed" record (for batches and workers);
    DEBUG keeps the traceback of an unexpected error in the record; AHEAD: the job's work
    done earlier in another thread (osmap_cli.batch), passed on to job.run."""
    started = time.monotonic()
    try:
        return job.run() if ahead is None else job.run(ahead)
    except OsmapError as exc:
        return failed_record(job, str(exc), started)
    except Exception as exc:  # noqa: BLE001 - one broken job must not stop the batch
        record = failed_record(job, f"{type(exc).__name__}: {exc}", started, internal=True)
        if debug:
            import traceback

            record["_traceback"] = traceback.format_exc()
        return record
