"""The mutation score of `make mutants`: per module, the mutants mutmut made and checked, how
many the tests killed, how many are listed as equivalent in tests/mutants_equivalent.txt (one
mutant name a line, `#` comments: the reasons), and how many survived that are not. It reads
the verdicts tests/mutation_run.py left in mutants/scores/.

    python tests/mutation_report.py schedule options organise output provenance batch

Exit status 1 when, in any module, more than 10 % of the non-equivalent mutants survive
(timeouts count as killed: the mutant hung a test; "no tests" count as survivors).
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCORES = ROOT / "mutants" / "scores"
KILLED = {1, 3, 36, 24, -24, 152, 255, 37}
SURVIVED = {0, 5, 33}
LIMIT = 0.10


def equivalents() -> set[str]:
    path = ROOT / "tests" / "mutants_equivalent.txt"
    lines = path.read_text("utf-8").splitlines() if path.exists() else []
    return {line.split("#")[0].strip() for line in lines if line.split("#")[0].strip()}


def count(verdicts: dict, known: set[str], survivors: list[str]) -> Counter:
    """The tally of one module's verdicts (name -> mutmut exit code); survivors are appended."""
    tally = Counter(mutants=len(verdicts))
    for name, code in sorted(verdicts.items()):
        if name in known:
            tally["equivalent"] += 1
        elif code is None:
            tally["not checked"] += 1
        elif code in KILLED:
            tally["killed"] += 1
        elif code in SURVIVED:
            tally["survived"] += 1
            survivors.append(name)
        else:
            tally["other"] += 1
    return tally


def main(modules: list[str]) -> int:
    known = equivalents()
    survivors: list[str] = []
    print(f"{'module':12} {'mutants':>8} {'killed':>7} {'equiv':>6} {'survived':>9} {'rate':>6}"
          "  commit   tests")
    failed = False
    for module in modules:
        path = SCORES / f"{module}.json"
        if not path.exists():
            print(f"{module:12} not run (python tests/mutation_run.py {module})")
            failed = True
            continue
        record = json.loads(path.read_text("utf-8"))
        tally = count(record["verdicts"], known, survivors)
        checked = tally["killed"] + tally["survived"]
        rate = tally["survived"] / checked if checked else 0.0
        failed |= not checked or rate > LIMIT or bool(tally["not checked"])
        tests = " ".join(Path(t).name for t in record["tests"] if not t.startswith("-"))
        line = (f"{module:12} {tally['mutants']:8d} {tally['killed']:7d} "
                f"{tally['equivalent']:6d} {tally['survived']:9d} {rate:6.1%}  "
                f"{record['commit']:8} {tests}")
        if tally["not checked"]:
            line += f"  ({tally['not checked']} not checked)"
        print(line)
    for name in survivors:
        print("survived:", name)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
