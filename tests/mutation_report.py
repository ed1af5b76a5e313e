"""The mutation score of `make mutants`: per module, the mutants mutmut made and checked (those
matching the PATTERNS given), how many the tests killed, and how many survived that are not
listed as equivalent in tests/mutants_equivalent.txt (one mutant name a line, `#` comments: the
reasons are in docs/testing.md).

    python tests/mutation_report.py 'osmap_cli.options*' 'osmap_cli.engine.xǁScheduleǁ*'

Exit status 1 when more than 10 % of the non-equivalent mutants survive (timeouts count as
killed: the mutant hung a test; "no tests" count as survivors).
"""

from __future__ import annotations

import fnmatch
import json
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KILLED = {1, 3, 36, 24, -24, 152, 255, 37}
SURVIVED = {0, 5, 33}
LIMIT = 0.10


def equivalents() -> set[str]:
    path = ROOT / "tests" / "mutants_equivalent.txt"
    lines = path.read_text("utf-8").splitlines() if path.exists() else []
    return {line.split("#")[0].strip() for line in lines if line.split("#")[0].strip()}


def main(patterns: list[str]) -> int:
    known = equivalents()
    rows, survivors = {}, []
    for meta in sorted((ROOT / "mutants").rglob("*.py.meta")):
        codes = json.loads(meta.read_text("utf-8"))["exit_code_by_key"]
        for name, code in codes.items():
            if patterns and not any(fnmatch.fnmatchcase(name, p) for p in patterns):
                continue
            module = name.split(".x")[0]
            count = rows.setdefault(module, Counter())
            count["mutants"] += 1
            if code is None:
                count["not checked"] += 1
            elif name in known:
                count["equivalent"] += 1
            elif code in KILLED:
                count["killed"] += 1
            elif code in SURVIVED:
                count["survived"] += 1
                survivors.append(name)
            else:
                count["other"] += 1
    total = Counter()
    print(f"{'module':32} {'mutants':>8} {'killed':>7} {'equiv':>6} {'survived':>9} {'rate':>6}")
    for module, count in sorted(rows.items()):
        total.update(count)
        print(_row(module, count))
    print(_row("all", total))
    for name in survivors:
        print("survived:", name)
    checked = total["killed"] + total["survived"]
    return 0 if checked and total["survived"] <= LIMIT * checked else 1


def _row(module: str, count: Counter) -> str:
    checked = count["killed"] + count["survived"]
    rate = count["survived"] / checked if checked else 0.0
    line = (f"{module:32} {count['mutants']:8d} {count['killed']:7d} {count['equivalent']:6d} "
            f"{count['survived']:9d} {rate:6.1%}")
    if count["not checked"]:
        line += f"  ({count['not checked']} not checked)"
    return line


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
