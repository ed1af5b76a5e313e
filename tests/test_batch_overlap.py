"""A batch in one process (-j 1) computes two jobs at a time when they allow it (Job.overlaps):
the jobs still commit and report in order, a failure or a skip is the same record, --fail-fast
commits nothing after the first failure, and a real synth batch writes the bytes of separate
runs. The stand-in jobs here take milliseconds."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from job_doubles import FileJob

from osmap_cli import batch
from osmap_cli.batch import run_jobs
from osmap_cli.errors import OsmapError

FAST = ("--size", "32", "--preset", "fast", "--levels", "2")


@dataclasses.dataclass(frozen=True)
class _Meet(FileJob):
    """Writes its name; its compute waits at `meeting` (a threading.Barrier) when given, so a
    run that never computes two jobs at once fails at the barrier."""

    meeting: object = None
    fails: bool = False
    stops: bool = False  # its compute raises KeyboardInterrupt, as a latched Ctrl-C does
    overlaps: bool = True

    def read(self):
        if self.fails:
            raise OsmapError(f"{self.exemplar}: not an image")
        return self.exemplar

    def compute(self, inputs):
        if self.meeting is not None:
            self.meeting.wait()
        if self.stops:
            raise KeyboardInterrupt
        return threading.current_thread().name

    def stage(self, outputs, inputs, result):
        assert threading.current_thread() is threading.main_thread()  # commits stay here
        outputs.stage(self.target, lambda temp: Path(temp).write_text(inputs))
        return f"wrote {self.target}", []


@pytest.fixture(autouse=True)
def _two_cores(monkeypatch):
    monkeypatch.setattr(batch.os, "cpu_count", lambda: 2)


def test_two_jobs_compute_at_once_and_commit_in_order(tmp_path, capsys):
    meeting = threading.Barrier(2, timeout=10)
    jobs = [_Meet(f"{n}.png", str(tmp_path / f"{n}.txt"), meeting=meeting) for n in "abcd"]
    assert run_jobs(jobs) == 0
    out, _ = capsys.readouterr()
    assert [line.split(" (")[0] for line in out.splitlines()] == [
        f"wrote {tmp_path / n}.txt" for n in "abcd"]
    assert [(tmp_path / f"{n}.txt").read_text() for n in "abcd"] == [
        f"{n}.png" for n in "abcd"]
    assert not [t for t in threading.enumerate() if t.name == "osmap-job"]


def test_jobs_that_do_not_overlap_run_one_at_a_time(tmp_path):
    """One job that may not overlap keeps the whole batch in turn (here a barrier of two would
    never be met: a short timeout fails the computes)."""
    meeting = threading.Barrier(2, timeout=0.5)
    jobs = [_Meet("a.png", str(tmp_path / "a.txt"), meeting=meeting),
            _Meet("b.png", str(tmp_path / "b.txt"), meeting=meeting, overlaps=False)]
    assert run_jobs(jobs, quiet=True) == 1
    assert not os.listdir(tmp_path)


def test_failures_skips_and_refusals_are_reported_in_order(tmp_path, capsys):
    (tmp_path / "c.txt").write_text("keep")
    jobs = [_Meet("a.png", str(tmp_path / "a.txt"), fails=True),
            _Meet("b.png", str(tmp_path / "b.txt"), refused="b.txt: refusing"),
            _Meet("c.png", str(tmp_path / "c.txt"), replace=False),
            _Meet("d.png", str(tmp_path / "d.txt"))]
    assert run_jobs(jobs, json_lines=True) == 1
    out, err = capsys.readouterr()
    assert [json.loads(line)["status"] for line in out.splitlines()] == [
        "failed", "failed", "skipped", "ok"]
    assert "a.png: not an image" in err and "b.txt: refusing" in err
    assert (tmp_path / "c.txt").read_text() == "keep"
    assert sorted(os.listdir(tmp_path)) == ["c.txt", "d.txt"]


def test_fail_fast_commits_nothing_after_the_first_failure(tmp_path, capsys):
    jobs = [_Meet("a.png", str(tmp_path / "a.txt"), fails=True),
            *(_Meet(f"{n}.png", str(tmp_path / f"{n}.txt")) for n in "bcd")]
    assert run_jobs(jobs, fail_fast=True) == 1
    _, err = capsys.readouterr()
    assert "1 failed, 3 not run (--fail-fast)" in err.splitlines()[-1]
    assert not os.listdir(tmp_path)
    assert not [t for t in threading.enumerate() if t.name == "osmap-job"]


def test_a_stop_in_a_job_computed_ahead_stops_the_batch_there(tmp_path):
    """Ctrl-C seen in a job computed in the other thread: the jobs before it are committed,
    it and those after are not, and the stop reaches the caller as itself."""
    jobs = [_Meet("a.png", str(tmp_path / "a.txt")), _Meet("b.png", str(tmp_path / "b.txt")),
            _Meet("c.png", str(tmp_path / "c.txt"), stops=True),
            _Meet("d.png", str(tmp_path / "d.txt"))]
    with pytest.raises(KeyboardInterrupt):
        run_jobs(jobs, quiet=True)
    assert sorted(os.listdir(tmp_path)) == ["a.txt", "b.txt"]


def test_a_synth_batch_writes_the_bytes_of_separate_runs(run_cli, twenty, tmp_path):
    together, separate = tmp_path / "together", tmp_path / "separate"
    result = run_cli("synth", *twenty[:4], "--out-dir", together, *FAST, "--quiet")
    assert result.code == 0, result.err
    separate.mkdir()
    for path in twenty[:4]:
        one = run_cli("synth", path, "-o", separate / path.name, *FAST, "--quiet")
        assert one.code == 0, one.err
        assert (together / path.name).read_bytes() == (separate / path.name).read_bytes()


def test_which_synth_jobs_overlap(tmp_path):
    from osmap_cli.synth.job import OVERLAP_PIXELS, SynthJob
    from osmap_cli.synth.options import SynthOptions

    def job(**changes):
        fields = {"options": SynthOptions(), **changes}
        return SynthJob(index=1, exemplar="a.png", output=str(tmp_path / "b.png"),
                        preset="default", preset_values={}, **fields)

    from osmap_kernels import parallel_launches_threadsafe

    assert job().overlaps == parallel_launches_threadsafe()
    assert not job(progress=True).overlaps  # one progress bar at a time
    side = int(OVERLAP_PIXELS ** 0.5) + 1
    big = job(options=SynthOptions(width=side, height=side))
    assert not big.overlaps


def test_no_overlap_when_the_threading_layer_is_not_threadsafe(tmp_path, monkeypatch):
    """Numba's workqueue layer aborts the process when two threads launch parallel kernels."""
    import osmap_kernels
    from osmap_cli.synth.job import SynthJob
    from osmap_cli.synth.options import SynthOptions

    job = SynthJob(index=1, exemplar="a.png", output=str(tmp_path / "b.png"), preset="default",
                   preset_values={}, options=SynthOptions())
    monkeypatch.setattr(osmap_kernels, "parallel_launches_threadsafe", lambda: False)
    assert not job.overlaps
    code = "import osmap_kernels; print(osmap_kernels.parallel_launches_threadsafe())"
    env = {**os.environ, "NUMBA_THREADING_LAYER": "workqueue"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
