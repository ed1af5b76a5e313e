"""Batches on a Dask cluster (--scheduler, --scheduler-file, --threads; osmap_cli.cluster).

A real distributed.LocalCluster on 127.0.0.1 (no other address), two single-process workers
with NUMBA_NUM_THREADS=2, shared by the tests of this module and closed at its end. Every
test has a time limit (SIGALRM), so a hung cluster fails the test instead of blocking the run.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
from conftest import json_lines

from osmap_cli.imageio import read_image
from osmap_cli.output import TEMP_PREFIX

FAST = ("--size", "32", "--preset", "fast", "--levels", "2")
TEST_SECONDS = 300  # the limit of one test, cluster start included (generous: 2 shared cores)

needs_distributed = pytest.mark.skipif(
    __import__("importlib").util.find_spec("distributed") is None,
    reason="dask.distributed is not installed (pip install 'osmap[cluster]')")


def _expire(signum, frame):
    raise TimeoutError(f"test_cluster: more than {TEST_SECONDS} s")


@pytest.fixture(autouse=True)
def time_limit():
    """Fail (not hang) a test that takes more than TEST_SECONDS."""
    previous = signal.signal(signal.SIGALRM, _expire)
    signal.alarm(TEST_SECONDS)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.fixture(scope="module")
def cluster(request):
    """The LocalCluster of `--scheduler local:2` (osmap_cli.cluster.start_local_cluster), but
    with NUMBA_NUM_THREADS=2 in its workers (for --threads 2)."""
    pytest.importorskip("distributed", reason="dask.distributed is not installed "
                        "(pip install 'osmap[cluster]')")
    from osmap_cli.cluster import start_local_cluster

    previous = signal.signal(signal.SIGALRM, _expire)
    signal.alarm(TEST_SECONDS)
    try:
        local = start_local_cluster(2, threads=2)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    request.addfinalizer(local.close)
    return local


def _serial(run_cli, exemplars, folder: Path, *args) -> None:
    """One `osmap synth X -o folder/X.name` per exemplar, in this process."""
    folder.mkdir(exist_ok=True)
    for path in exemplars:
        one = run_cli("synth", path, "-o", folder / path.name, *FAST, *args, "--quiet")
        assert one.code == 0, one.err


def _visible(folder: Path) -> list[str]:
    """The files in FOLDER, without the hidden temporary files of output transactions."""
    return sorted(n for n in os.listdir(folder) if not n.startswith(TEMP_PREFIX))


# ---------------------------------------------------------------------------------------------
# the cluster


@needs_distributed
def test_the_cluster_listens_on_loopback_only(cluster):
    """And its scheduler retries a task whose worker died once, and gives a worker only the
    task it runs (a dying worker takes no queued task with it)."""
    from distributed import Client

    assert cluster.scheduler.allowed_failures == 1
    assert cluster.scheduler.WORKER_SATURATION == 1.0
    assert cluster.scheduler.http_server.address == "127.0.0.1"

    with Client(cluster.scheduler_address, timeout=60) as client:
        client.wait_for_workers(2, timeout=120)
        info = client.scheduler_info()
    assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
    assert len(info["workers"]) == 2
    for address, worker in info["workers"].items():
        assert address.startswith("tcp://127.0.0.1:"), address
        assert worker["nanny"].startswith("tcp://127.0.0.1:"), worker["nanny"]
        assert worker["nthreads"] == 1


@needs_distributed
def test_twenty_exemplars_give_the_bytes_of_twenty_serial_runs(cluster, run_cli, twenty,
                                                               tmp_path, monkeypatch):
    """Acceptance; also: a relative --out-dir means the client's folder on the workers."""
    monkeypatch.chdir(tmp_path)
    result = run_cli("synth", *twenty, "--out-dir", "batch", "--json", *FAST, "--seed", "4",
                     "--scheduler", cluster.scheduler_address)
    assert result.code == 0, result.err
    records = json_lines(result.out)  # stdout holds nothing but the JSON objects
    assert len(records) == 20 and {r["status"] for r in records} == {"ok"}
    assert sorted(r["input"] for r in records) == sorted(map(str, twenty))
    assert {r["outputs"][0] for r in records} == {f"batch/{p.name}" for p in twenty}
    assert "20 jobs: 20 written, 0 skipped, 0 failed" in result.err_lines[-1]
    _serial(run_cli, twenty, tmp_path / "serial", "--seed", "4")
    assert _visible(tmp_path / "batch") == sorted(p.name for p in twenty)
    for path in twenty:
        assert (tmp_path / "batch" / path.name).read_bytes() == \
            (tmp_path / "serial" / path.name).read_bytes(), path


@needs_distributed
def test_a_broken_input_is_one_failed_job(cluster, run_cli, twenty, tmp_path):
    bad = tmp_path / "broken.png"
    bad.write_text("not an image")
    out = tmp_path / "out"
    result = run_cli("synth", twenty[0], bad, *twenty[1:3], "--out-dir", out, *FAST, "--json",
                     "--scheduler", cluster.scheduler_address)
    assert result.code == 1
    records = json_lines(result.out)
    assert sorted(r["status"] for r in records) == ["failed", "ok", "ok", "ok"]
    failed = [r for r in records if r["status"] == "failed"]
    assert failed[0]["input"] == str(bad) and "broken.png" in failed[0]["error"]
    errors = [line for line in result.err_lines if line.startswith("osmap: error:")]
    assert len(errors) == 1 and "broken.png" in errors[0]
    assert result.err_lines[-1].startswith("osmap: 4 jobs: 3 written, 0 skipped, 1 failed")
    assert _visible(out) == sorted(p.name for p in twenty[:3])


@needs_distributed
def test_skip_overwrite_text_mode_and_one_output(cluster, run_cli, twenty, tmp_path):
    """The skip / overwrite rules and the text lines of -j; -o is one task on the cluster."""
    address = ("--scheduler", cluster.scheduler_address)
    out = tmp_path / "out"
    out.mkdir()
    kept = out / twenty[0].name
    kept.write_bytes(b"keep me")
    result = run_cli("synth", *twenty[:2], "--out-dir", out, *FAST, *address)
    assert result.code == 0, result.err
    lines = result.out.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"wrote {out / twenty[1].name}"), lines
    assert any("skipped" in line and "--overwrite" in line for line in result.err_lines)
    assert kept.read_bytes() == b"keep me"
    result = run_cli("synth", *twenty[:2], "--out-dir", out, *FAST, *address, "--overwrite",
                     "--quiet")
    assert result.code == 0, result.err
    assert read_image(kept).pixels.shape == (32, 32, 3)
    single = run_cli("synth", twenty[0], "-o", tmp_path / "one.png", *FAST, *address, "-q")
    assert single.code == 0, single.err
    assert (tmp_path / "one.png").read_bytes() == kept.read_bytes()


@needs_distributed
def test_threads_do_not_change_the_bytes(cluster, run_cli, twenty, tmp_path):
    address = ("--scheduler", cluster.scheduler_address)
    for threads in ("1", "2"):
        result = run_cli("synth", *twenty[:2], "--out-dir", tmp_path / threads, *FAST,
                         *address, "--threads", threads)
        assert result.code == 0, result.err
        assert "warning" not in result.err
    for path in twenty[:2]:
        assert (tmp_path / "1" / path.name).read_bytes() == \
            (tmp_path / "2" / path.name).read_bytes()
    # more threads than the workers' NUMBA_NUM_THREADS: capped, said, same bytes
    result = run_cli("synth", twenty[0], "--out-dir", tmp_path / "3", *FAST, *address,
                     "--threads", "3", "--json")
    assert result.code == 0, result.err
    assert "--threads 3: this worker has at most 2 Numba threads" in result.err
    assert (tmp_path / "3" / twenty[0].name).read_bytes() == \
        (tmp_path / "1" / twenty[0].name).read_bytes()


@needs_distributed
def test_solid_batch_on_the_cluster_matches_separate_runs(cluster, run_cli, twenty, tmp_path):
    solid = ("--size", "16", "--preset", "fast", "--seed", "2")
    out = tmp_path / "out"
    result = run_cli("solid", *twenty[:2], "--out-dir", out, *solid, "--json",
                     "--preview", "{stem}_preview.png", "--scheduler", cluster.scheduler_address)
    assert result.code == 0, result.err
    assert [r["status"] for r in json_lines(result.out)] == ["ok", "ok"]
    for path in twenty[:2]:
        single = tmp_path / f"single_{path.stem}.npy"
        one = run_cli("solid", path, "-o", single, *solid, "--quiet")
        assert one.code == 0, one.err
        assert (out / f"{path.stem}.npy").read_bytes() == single.read_bytes()
        assert (out / f"{path.stem}_preview.png").exists()


@needs_distributed
def test_scheduler_file(cluster, run_cli, twenty, tmp_path):
    # the shape `dask scheduler --scheduler-file` writes (its identity; Client reads "address")
    path = tmp_path / "scheduler.json"
    path.write_text(json.dumps({"type": "Scheduler", "id": "test",
                                "address": cluster.scheduler_address}))
    result = run_cli("synth", *twenty[:2], "--out-dir", tmp_path / "out", *FAST, "--json",
                     "--scheduler-file", path)
    assert result.code == 0, result.err
    assert [r["status"] for r in json_lines(result.out)] == ["ok", "ok"]


@needs_distributed
def test_fail_fast_starts_no_job_after_the_failure(cluster, run_cli, twenty, tmp_path):
    missing = tmp_path / "missing.png"
    out = tmp_path / "out"
    result = run_cli("synth", missing, *twenty[:10], "--out-dir", out, *FAST, "--fail-fast",
                     "--json", "--scheduler", cluster.scheduler_address)
    assert result.code == 1
    records = json_lines(result.out)
    statuses = [r["status"] for r in records]
    assert statuses.count("failed") == 1 and set(statuses) <= {"ok", "failed"}
    summary = result.err_lines[-1]
    not_run = 10 - statuses.count("ok")
    # jobs already running when the failure came back finish; the others never start
    assert not_run >= 1, summary
    assert f"1 failed, {not_run} not run (--fail-fast)" in summary
    # an output exists exactly for each job reported written: nothing ran unreported
    written = sorted(os.path.basename(r["outputs"][0]) for r in records if r["status"] == "ok")
    assert _visible(out) == written


# ---------------------------------------------------------------------------------------------
# a worker killed mid-task (SIGKILL)


def _synth_jobs(exemplars, folder: Path):
    from osmap_cli.synth.job import SynthJob
    from osmap_cli.synth.options import SynthOptions

    options = SynthOptions(width=32, height=32, levels=2, seed=3).validated()
    return [SynthJob(index=i, exemplar=str(path), output=str(folder / path.name),
                     options=options, preset="default", preset_values={}, replace=False)
            for i, path in enumerate(exemplars, 1)]


@dataclasses.dataclass(frozen=True)
class _Killer:
    """Stands in for a job: SIGKILLs its worker process in the middle of the job (after
    its outputs are staged, before they are committed), on the first ``times`` attempts."""

    job: object
    marker: str
    times: int

    def __getattr__(self, name):
        if name.startswith("__") or name == "job":  # while unpickling
            raise AttributeError(name)
        return getattr(self.job, name)

    def run(self):
        from osmap_cli.output import Outputs

        attempts = len(os.listdir(self.marker))
        if attempts >= self.times:
            return self.job.run()
        Path(self.marker, uuid.uuid4().hex).write_text(str(os.getpid()))
        inputs = self.job.read()
        result = self.job.compute(inputs)
        with Outputs() as outputs:
            self.job.stage(outputs, inputs, result)  # the temporary files exist now
            os.kill(os.getpid(), signal.SIGKILL)


@dataclasses.dataclass(frozen=True)
class _ThreadProbe:
    """Stands in for a job: runs it and adds the Numba thread count it ran with."""

    job: object

    def __getattr__(self, name):
        if name.startswith("__") or name == "job":  # while unpickling
            raise AttributeError(name)
        return getattr(self.job, name)

    def run(self):
        import numba

        record = self.job.run()
        record["threads"] = numba.get_num_threads()
        return record


@needs_distributed
@pytest.mark.parametrize("threads", [1, 2])
def test_each_task_runs_with_the_threads_asked_for(cluster, twenty, tmp_path, capsys, threads):
    jobs = [_ThreadProbe(job) for job in _synth_jobs(twenty[:2], tmp_path)]
    assert _run_on(cluster, jobs, threads=threads) == 0
    records = json_lines(capsys.readouterr().out)
    assert [r["threads"] for r in records] == [threads, threads]


def _run_on(cluster, jobs, threads: int = 1, **kwargs) -> int:
    import cloudpickle

    from osmap_cli.batch import run_jobs
    from osmap_cli.cluster import ClusterSpec

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import it
    try:
        return run_jobs(jobs, json_lines=True,
                        cluster=ClusterSpec(address=cluster.scheduler_address,
                                            threads=threads), **kwargs)
    finally:
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


@needs_distributed
@pytest.mark.parametrize("kills", [1, 2])
def test_a_worker_killed_mid_task_loses_and_corrupts_nothing(cluster, twenty, tmp_path,
                                                              capsys, kills):
    """Killed once: the task runs again on a (restarted) worker and every output has the bytes
    of a serial run. Killed on the retry too: that job is reported failed, the rest are
    written, exit 1, and no half-written output is left under an output's name."""
    out, serial = tmp_path / "out", tmp_path / "serial"
    out.mkdir()
    serial.mkdir()
    marker = tmp_path / "marker"
    marker.mkdir()
    jobs = _synth_jobs(twenty[:6], out)
    jobs[2] = _Killer(jobs[2], str(marker), kills)
    code = _run_on(cluster, jobs)
    records = json_lines(capsys.readouterr().out)
    assert len(os.listdir(marker)) == kills  # the worker really was killed, KILLS times
    by_input = {r["input"]: r for r in records}
    assert len(records) == 6 and len(by_input) == 6
    victim = by_input[str(twenty[2])]
    if kills == 1:
        assert code == 0 and victim["status"] == "ok"
        expected = sorted(p.name for p in twenty[:6])
    else:
        assert code == 1 and victim["status"] == "failed"
        assert "died" in victim["error"] and "KilledWorker" in victim["error"]
        expected = sorted(p.name for i, p in enumerate(twenty[:6]) if i != 2)
    assert [r["status"] for r in records].count("ok") == len(expected)
    assert _visible(out) == expected
    from osmap_cli.batch import run_jobs

    assert run_jobs(_synth_jobs(twenty[:6], serial), quiet=True) == 0
    for name in expected:
        assert (out / name).read_bytes() == (serial / name).read_bytes(), name


# ---------------------------------------------------------------------------------------------
# local:N, usage errors, imports


@needs_distributed
def test_local_n_starts_a_loopback_cluster_and_closes_it(run_cli, twenty, tmp_path,
                                                         monkeypatch):
    import distributed

    started = []

    class Recording(distributed.LocalCluster):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.started_workers = len(self.workers)
            started.append(self)

    monkeypatch.setattr(distributed, "LocalCluster", Recording)
    result = run_cli("synth", *twenty[:2], "--out-dir", tmp_path / "out", *FAST,
                     "--scheduler", "local:3", "--json")
    assert result.code == 0, result.err
    assert [r["status"] for r in json_lines(result.out)] == ["ok", "ok"]
    (local,) = started
    assert local.started_workers == 2  # local:3 for 2 jobs: no idle worker is started
    assert local.scheduler_address.startswith("tcp://127.0.0.1:")
    assert local.scheduler.http_server.address == "127.0.0.1"
    assert local.status.name == "closed"
    _serial(run_cli, twenty[:2], tmp_path / "serial")
    for path in twenty[:2]:
        assert (tmp_path / "out" / path.name).read_bytes() == \
            (tmp_path / "serial" / path.name).read_bytes()


@needs_distributed
def test_an_unreachable_scheduler_is_an_error_not_a_hang(run_cli, twenty, tmp_path):
    import dask

    with dask.config.set({"distributed.comm.timeouts.connect": "2s"}):
        # port 1 on the loopback interface: nothing listens there
        result = run_cli("synth", *twenty[:2], "--out-dir", tmp_path / "o", *FAST,
                         "--scheduler", "tcp://127.0.0.1:1")
    assert result.code == 1, result.err
    assert "cannot connect to the Dask scheduler (tcp://127.0.0.1:1)" in result.err
    assert os.listdir(tmp_path / "o") == []


@pytest.mark.parametrize("args, needle", [
    (["--scheduler", "local:2", "-j", "2"], "-j/--jobs"),
    (["--scheduler", "local:0"], "local:N"),
    (["--scheduler", "local:two"], "local:N"),
    (["--threads", "2"], "--threads works with --scheduler"),
    (["--scheduler", "tcp://127.0.0.1:1", "--scheduler-file", "{file}"], "not both"),
])
def test_usage_errors_exit_2(run_cli, twenty, tmp_path, args, needle):
    (tmp_path / "s.json").write_text("{}")
    args = [a.replace("{file}", str(tmp_path / "s.json")) for a in args]
    result = run_cli("synth", *twenty[:2], "--out-dir", tmp_path / "o", *FAST, *args)
    assert result.code == 2, result.err
    assert needle in result.err
    assert not (tmp_path / "o").exists() or os.listdir(tmp_path / "o") == []


def test_without_distributed_scheduler_is_a_usage_error_naming_the_extra(run_cli, twenty,
                                                                         tmp_path, monkeypatch):
    monkeypatch.setattr("osmap_cli.cluster.available", lambda: False)
    for command in ("synth", "solid"):
        result = run_cli(command, twenty[0], "--out-dir", tmp_path / "o", "--scheduler",
                         "local:1")
        assert result.code == 2, result.err
        assert "pip install 'osmap[cluster]'" in result.err


def test_help_and_plain_runs_do_not_import_dask(twenty, tmp_path):
    code = (
        "import sys\n"
        "from osmap_cli.cli import main\n"
        "assert main(['--help']) == 0\n"
        "assert main(['synth', '--help']) == 0\n"
        "assert main(['solid', '--help']) == 0\n"
        f"assert main(['synth', {str(twenty[0])!r}, '-o', {str(tmp_path / 'a.png')!r}, "
        "'--size', '32', '--preset', 'fast', '--levels', '2', '-q']) == 0\n"
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed'))\n"
        "assert not loaded, loaded\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=TEST_SECONDS)
    assert done.returncode == 0, done.stderr
    assert "--scheduler" in done.stdout and "--threads" in done.stdout
    assert (tmp_path / "a.png").exists()
