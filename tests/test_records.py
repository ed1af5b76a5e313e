"""A finished job's record (osmap_cli.records) and how a batch reports it (batch._Reporter):
the failure of one job is one line naming its exemplar, an unexpected error is marked as
internal (its traceback kept only with --debug). The batches themselves are in test_batch.py;
these check the records in milliseconds."""

from __future__ import annotations

import json

import pytest

from osmap_cli import records
from osmap_cli.batch import _Reporter
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
