"""A finished job's record (osmap_cli.records), how a batch reports it (batch._Reporter) and
where run_jobs sends the jobs (here, the worker pool, a cluster): the failure of one job is one
line naming its exemplar, an unexpected error is marked as internal (its traceback kept only
with --debug). Real batches are in test_batch.py; these use jobs that write a line of text, in
milliseconds."""

from __future__ import annotations

import dataclasses
import json
import os
import re
from pathlib import Path

import pytest
from job_doubles import FileJob

from osmap_cli import records
from osmap_cli.batch import _Reporter, run_jobs
from osmap_cli.errors import OsmapError
from osmap_cli.records import failed_record, job_record, run_caught


class _Job:
    exemplar = "in/cells.png"

    def __init__(self, fails: BaseException | None = None):
        self.fails = fails

    def describe(self) -> dict:
        return {"input": self.exemplar, "outputs": ["out/cells.png"]}

    def run(self) -> dict:
        if self.fails is not None:
            raise self.fails
        return job_record(self, "ok", 0.0)


def test_a_record_holds_the_job_its_time_and_status(monkeypatch):
    monkeypatch.setattr(records.time, "monotonic", lambda: 100.0)
    record = job_record(_Job(), "skipped", 97.65432, reason="exists")
    assert list(record) == ["input", "outputs", "seconds", "status", "reason"]
    assert record["status"] == "skipped" and record["reason"] == "exists"
    assert record["seconds"] == 2.346  # milliseconds


def test_a_failure_is_one_line_naming_the_exemplar_once():
    record = failed_record(_Job(), "cannot read\n  the file", 0.0)
    assert record["error"] == "in/cells.png: cannot read the file"
    assert record["status"] == "failed" and record["_internal"] is False
    named = failed_record(_Job(), "in/cells.png: not an image", 0.0, internal=True)
    assert named["error"] == "in/cells.png: not an image" and named["_internal"] is True


def test_run_caught_turns_errors_into_records():
    assert run_caught(_Job())["status"] == "ok"
    bad = run_caught(_Job(OsmapError("in/cells.png: truncated file")))
    assert bad["error"] == "in/cells.png: truncated file"
    assert bad["_internal"] is False and "_traceback" not in bad
    broken = run_caught(_Job(ValueError("boom")))
    assert broken["error"] == "in/cells.png: ValueError: boom" and broken["_internal"] is True
    assert "_traceback" not in broken
    traced = run_caught(_Job(ValueError("boom")), debug=True)
    assert traced["_traceback"].startswith("Traceback") and "ValueError: boom" in traced[
        "_traceback"]
    with pytest.raises(KeyboardInterrupt):  # a stop is not one job's failure
        run_caught(_Job(KeyboardInterrupt()))


@pytest.mark.parametrize("json_lines", [False, True], ids=["text", "json"])
def test_the_reporter_prints_each_outcome(capsys, json_lines):
    report = _Reporter(json_lines=json_lines, quiet=False, debug=False)
    ok = {**job_record(_Job(), "ok", 0.0), "_line": "wrote out/cells.png (0.1 s)",
          "_warnings": ["exemplar is small"]}
    report(ok)
    report(job_record(_Job(), "skipped", 0.0, reason="out/cells.png exists"))
    report(failed_record(_Job(), "bad", 0.0))
    report(failed_record(_Job(), "KeyError: 3", 0.0, internal=True))
    out, err = capsys.readouterr()
    assert err.splitlines() == ["osmap: warning: exemplar is small",
                                "osmap: skipped in/cells.png: out/cells.png exists",
                                "osmap: error: in/cells.png: bad",
                                "osmap: internal error: in/cells.png: KeyError: 3"]
    assert report.counts == {"ok": 1, "skipped": 1, "failed": 2}
    if json_lines:
        lines = [json.loads(line) for line in out.splitlines()]
        assert [r["status"] for r in lines] == ["ok", "skipped", "failed", "failed"]
        assert list(lines[1]) == ["input", "outputs", "seconds", "status", "reason"]  # in order
        assert not [key for r in lines for key in r if key.startswith("_")]
    else:
        assert out.splitlines() == ["wrote out/cells.png (0.1 s)"]


def test_a_quiet_reporter_prints_failures_only(capsys):
    report = _Reporter(json_lines=False, quiet=True, debug=False)
    report({**job_record(_Job(), "ok", 0.0), "_line": "wrote", "_warnings": ["w"]})
    report(job_record(_Job(), "skipped", 0.0, reason="exists"))
    traced = run_caught(_Job(ValueError("boom")), debug=True)
    report(traced)
    out, err = capsys.readouterr()
    assert out == ""
    # the traceback (--debug), then the one error line, nothing between them
    assert err.startswith("Traceback") and err.splitlines()[-2:] == [
        "ValueError: boom", "osmap: internal error: in/cells.png: ValueError: boom"]


@dataclasses.dataclass(frozen=True)
class _Write(FileJob):
    """A job that writes the id of the process that ran it (or fails as told)."""

    fails: str = ""  # "", "error" or "internal"

    def read(self):
        if self.fails == "error":
            raise OsmapError(f"{self.exemplar}: not an image")
        if self.fails == "internal":
            raise KeyError("lost")
        return os.getpid()

    def compute(self, inputs):
        return inputs

    def stage(self, outputs, inputs, result):
        outputs.stage(self.target, lambda temp: Path(temp).write_text(str(result)))
        return f"wrote {self.target}", ["small exemplar"]


def test_a_job_runs_read_to_commit_and_keeps_its_warnings(tmp_path):
    record = _Write("a.png", str(tmp_path / "a.txt")).run()
    assert record["status"] == "ok" and record["_warnings"] == ["small exemplar"]
    assert re.fullmatch(rf"wrote {re.escape(str(tmp_path))}/a\.txt \(\d+\.\d s\)",
                        record["_line"])
    assert (tmp_path / "a.txt").read_text() == str(os.getpid())


def test_run_jobs_by_default_runs_every_job_here_and_reports_text(tmp_path, capsys):
    """The defaults: one job after another in this process, a failure does not stop the
    others, a line per job on stdout, warnings, errors and the summary on stderr, no
    traceback."""
    jobs = [_Write("a.png", str(tmp_path / "a.txt"), fails="internal"),
            _Write("b.png", str(tmp_path / "b.txt")), _Write("c.png", str(tmp_path / "c.txt"))]
    assert run_jobs(jobs) == 1
    out, err = capsys.readouterr()
    assert [line.split(" (")[0] for line in out.splitlines()] == [
        f"wrote {tmp_path / 'b.txt'}", f"wrote {tmp_path / 'c.txt'}"]
    lines = err.splitlines()
    assert lines[:-1] == ["osmap: internal error: a.png: KeyError: 'lost'",
                          "osmap: warning: small exemplar", "osmap: warning: small exemplar"]
    assert lines[-1].startswith("osmap: 3 jobs: 2 written, 0 skipped, 1 failed (")
    assert sorted(os.listdir(tmp_path)) == ["b.txt", "c.txt"]
    assert {(tmp_path / n).read_text() for n in ("b.txt", "c.txt")} == {str(os.getpid())}


def test_run_jobs_quiet_with_debug_prints_the_failure_and_its_traceback(tmp_path, capsys):
    jobs = [_Write("a.png", str(tmp_path / "a.txt")),
            _Write("b.png", str(tmp_path / "b.txt"), fails="internal")]
    assert run_jobs(jobs, quiet=True, debug=True) == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("Traceback") and err.splitlines()[-1] == (
        "osmap: internal error: b.png: KeyError: 'lost'")


def test_a_single_job_raises_its_error_and_reports_no_summary(tmp_path, capsys):
    """`osmap synth X -o Y`: one job's failure is the command's failure (raised, reported like
    any other); a single job that succeeds prints its line and no summary."""
    with pytest.raises(OsmapError, match=r"^a\.png: not an image$"):
        run_jobs([_Write("a.png", str(tmp_path / "a.txt"), fails="error")])
    assert run_jobs([_Write("b.png", str(tmp_path / "b.txt"))]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"wrote {tmp_path / 'b.txt'} (")
    assert err.splitlines() == ["osmap: warning: small exemplar"]


def _first_job_runner(calls: list):
    """A stand-in for the worker pool or a cluster: notes how it was called (the jobs, -j or
    the cluster, --fail-fast, --debug), runs the first job here, reports the others not run."""

    def run(jobs, where, fail_fast, debug, report):
        calls.append((jobs, where, fail_fast, debug))
        report(run_caught(jobs[0], debug))
        return len(jobs) - 1

    return run


def test_a_cluster_runs_every_job_with_the_run_s_settings(tmp_path, monkeypatch, capsys):
    """--scheduler: every job, even a single one, goes to the cluster with --fail-fast and
    --debug; the jobs it did not run appear in the summary."""
    from osmap_cli import cluster

    calls = []
    monkeypatch.setattr(cluster, "run_cluster", _first_job_runner(calls))
    jobs = [_Write("a.png", str(tmp_path / "a.txt"), fails="error"),
            _Write("b.png", str(tmp_path / "b.txt"))]
    assert run_jobs(jobs, fail_fast=True, debug=True, cluster="spec") == 1
    assert run_jobs(jobs[1:], cluster="spec") == 0
    assert calls == [(jobs, "spec", True, True), (jobs[1:], "spec", False, False)]
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "osmap: error: a.png: not an image"
    assert err[1].startswith("osmap: 2 jobs: 0 written, 0 skipped, 1 failed, 1 not run "
                             "(--fail-fast) (")


def test_workers_run_the_jobs_in_a_pool_with_the_run_s_settings(tmp_path, monkeypatch,
                                                                 capsys):
    """-j N with several jobs hands them to the worker pool (its own test: test_batch.py's
    -j 2 batch); one job, or -j 1, runs here. The summary counts what the pool did not run
    and the seconds since the batch began."""
    from osmap_cli import batch

    calls = []
    monkeypatch.setattr(batch, "_run_pool", _first_job_runner(calls))
    monkeypatch.setattr(batch.time, "monotonic", lambda: 100.0)
    jobs = [_Write("a.png", str(tmp_path / "a.txt"), fails="error"),
            _Write("b.png", str(tmp_path / "b.txt"))]
    assert run_jobs(jobs, workers=2, fail_fast=True, debug=True) == 1
    assert calls == [(jobs, 2, True, True)]
    assert capsys.readouterr().err.splitlines() == [
        "osmap: error: a.png: not an image",
        "osmap: 2 jobs: 0 written, 0 skipped, 1 failed, 1 not run (--fail-fast) (0.0 s)"]
    assert run_jobs(jobs[1:], workers=2, json_lines=True) == 0  # one job: here, no summary
    assert run_jobs(jobs[1:] * 3, workers=1) == 0
    assert len(calls) == 1
    err = capsys.readouterr().err.splitlines()
    assert err[:-1] == ["osmap: warning: small exemplar"] * 4
    assert err[-1] == "osmap: 3 jobs: 3 written, 0 skipped, 0 failed (0.0 s)"


def test_fail_fast_counts_the_jobs_after_the_failure(tmp_path, capsys):
    jobs = [_Write("a.png", str(tmp_path / "a.txt")),
            _Write("b.png", str(tmp_path / "b.txt"), fails="error"),
            _Write("c.png", str(tmp_path / "c.txt")), _Write("d.png", str(tmp_path / "d.txt"))]
    assert run_jobs(jobs, fail_fast=True, quiet=True) == 1
    assert run_jobs(jobs, fail_fast=True) == 1
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "osmap: error: b.png: not an image"  # quiet: the failure only
    assert err[-1].startswith("osmap: 4 jobs: 1 written, 0 skipped, 1 failed, 2 not run")
    assert sorted(os.listdir(tmp_path)) == ["a.txt"]
