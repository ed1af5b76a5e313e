"""`make mutants`: mutmut over one module at a time, each with the test files aimed at it
(docs/testing.md, "Mutation testing").

    python tests/mutation_run.py provenance [--max-children=1]
    python tests/mutation_run.py provenance --survivors    # only the last run's survivors

One mutmut run per module: mutmut maps each function to the tests of its test selection that
reach it and runs those for each mutant, so a narrow selection keeps a module's run short (every
command writes through output.py and reads options.py: with the whole suite each of their
mutants would run hundreds of syntheses). A run starts from a fresh copy of the package in
mutants/ (mutmut does not refresh a copied module that it does not mutate) and leaves its
verdicts in mutants/scores/MODULE.json, which tests/mutation_report.py reads; --survivors
checks again only the mutants that survived there (not listed as equivalent), after new tests,
and updates their verdicts. The shared settings (files to mutate, the fork server, the
timeout) are in [tool.mutmut] of pyproject.toml.
"""

from __future__ import annotations

import fnmatch
import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCORES = ROOT / "mutants" / "scores"
SURVIVED = {0, 5, 33}  # mutmut's exit codes of a mutant that no test killed

# module -> (mutant name patterns, test files)
MODULES = {
    "schedule": (["osmap_cli.engine.xǁScheduleǁvalues*"],
                 ["tests/test_engine.py"]),
    "options": (["osmap_cli.options.*"],
                ["tests/test_options.py", "tests/test_presets.py"]),
    "organise": (["osmap_cli.synth.organise.*"],
                 ["tests/test_mechanisms.py"]),
    "output": (["osmap_cli.output.*"],
               ["tests/test_durability.py", "tests/test_imageio.py"]),
    "provenance": (["osmap_cli.provenance.*"],
                   ["tests/test_provenance.py", "tests/test_info.py"]),
    # the code a batch runs in this process and reports with, without the -j 2 batch (15 s a
    # mutant): the worker pool's functions (_run_pool, _init_worker, _worker_job, run_jobs'
    # branch to them) are left to test_batch.py's -j 2 test in the suite
    "batch": (["osmap_cli.batch.xǁJobǁ*", "osmap_cli.batch.x_skip_or_refuse*",
               "osmap_cli.batch.x_run_jobs*", "osmap_cli.batch.xǁ_Reporterǁ*",
               "osmap_cli.batch.x__say*", "osmap_cli.records.*"],
              ["tests/test_records.py", "tests/test_batch.py",
               "--deselect=tests/test_batch.py::test_batch_j2_gives_the_bytes_of_separate_runs"]),
}


def _fresh_copy() -> None:
    """Remove mutmut's copy of the package and its state; keep the scores of other modules."""
    folder = ROOT / "mutants"
    if folder.is_dir():
        for entry in folder.iterdir():
            if entry != SCORES:
                shutil.rmtree(entry) if entry.is_dir() else entry.unlink()


def _verdicts(patterns: list[str]) -> dict[str, int | None]:
    codes: dict[str, int | None] = {}
    for meta in sorted((ROOT / "mutants").rglob("*.py.meta")):
        for name, code in json.loads(meta.read_text("utf-8"))["exit_code_by_key"].items():
            if any(fnmatch.fnmatchcase(name, p) for p in patterns):
                codes[name] = code
    return codes


def _survivors(module: str) -> tuple[dict, list[str]]:
    """The last record of MODULE and its survivors that are not listed as equivalent."""
    record = json.loads((SCORES / f"{module}.json").read_text("utf-8"))
    lines = (ROOT / "tests" / "mutants_equivalent.txt").read_text("utf-8").splitlines()
    known = {line.split("#")[0].strip() for line in lines}
    return record, [name for name, code in record["verdicts"].items()
                    if code in SURVIVED and name not in known]


def run(module: str, max_children: int, survivors: bool = False) -> int:
    """mutmut over MODULE with its test files (SURVIVORS: over the last run's survivors);
    returns mutmut's exit code."""
    import mutmut.configuration
    from mutmut.__main__ import cli

    patterns, tests = MODULES[module]
    record = {"module": module, "tests": tests, "verdicts": {}}
    if survivors:
        record, patterns = _survivors(module)
        if not patterns:
            return 0
    config = mutmut.configuration.config()
    config.pytest_add_cli_args_test_selection = list(tests)
    try:
        cli(["run", "--max-children", str(max_children), *patterns], standalone_mode=False)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    SCORES.mkdir(parents=True, exist_ok=True)
    record["commit"] = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                      text=True, capture_output=True).stdout.strip()
    record["verdicts"].update(_verdicts(patterns))
    if survivors:
        record["rechecked"] = patterns
    (SCORES / f"{module}.json").write_text(json.dumps(record, indent=1), "utf-8")
    return code


def main(argv: list[str]) -> int:
    survivors = "--survivors" in argv
    args = [a for a in argv if not a.startswith("--max-children") and a != "--survivors"]
    children = next((int(a.split("=", 1)[1]) for a in argv if a.startswith("--max-children=")),
                    1)
    unknown = [a for a in args if a not in MODULES]
    if len(args) != 1 or unknown:
        print("usage: mutation_run.py MODULE [--max-children=N] [--survivors]; modules: "
              + ", ".join(MODULES), file=sys.stderr)
        return 2
    # run from the repository root, with nothing of tests/ importable but through pytest
    here = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if str(Path(p or ".").resolve()) != here]
    _fresh_copy()
    return run(args[0], children, survivors)


if __name__ == "__main__":
    import os

    os.chdir(ROOT)
    sys.exit(main(sys.argv[1:]))
