"""Run every benchmark (benchmarks/bench_*.py) and print one table.

Speeds are reported as ratios to a baseline measured in the same run, so
they compare across machines; absolute figures are printed for reference.
Exit status 1 when a target is missed.

    make bench                  # all
    python benchmarks/run.py one_dof_loop   # only bench_one_dof_loop.py
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main(argv: list[str]) -> int:
    names = argv or sorted(p.stem[len("bench_"):] for p in (ROOT / "benchmarks").glob("bench_*.py"))
    rows = []
    for name in names:
        module = importlib.import_module(f"benchmarks.bench_{name}")
        print(f"running {name} ...", file=sys.stderr, flush=True)
        rows += module.run()
    header = ("benchmark", "measure", "value", "target", "")
    table = [header] + [
        (r.benchmark, r.measure, f"{r.value:.3g} {r.unit}", r.target,
         "" if r.ok is None else ("ok" if r.ok else "MISSED"))
        for r in rows
    ]
    widths = [max(len(row[k]) for row in table) for k in range(len(header))]
    for k, row in enumerate(table):
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip())
        if k == 0:
            print("  ".join("-" * w for w in widths))
    return 1 if any(r.ok is False for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
