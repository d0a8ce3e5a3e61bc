#!/usr/bin/env python3
"""Keeps the README's quotes of the first command equal to what that command prints.

Maps the bundled example street as ./scripts/run_example.sh does (`shine map -o OUT`, no other
argument) and checks that
  - the README's block of printed figures (between the markers `<!-- example figures -->` and
    `<!-- /example figures -->`) holds the metric lines the run printed, and
  - the results table's row for the example (the line starting `| bundled street` and naming
    `run_example.sh`) quotes the printed accuracy, F-score and map size.
Figures may differ from the printed ones by at most TOLERANCE in their last digits: the same
commit printed F 95.41 % / accuracy 4.79 cm on one host and 95.39 % / 4.80 cm on another (an
AMD EPYC with AVX-512), the run being deterministic on each. The map size must be exact.

Usage: readme_example_figures.py SHINE README.md WORK_DIR
"""

import re
import shutil
import subprocess
import sys
from pathlib import Path

METRIC_LINE = re.compile(
    r"^(accuracy|completion|Chamfer-L1|precision|completion ratio|F-score)\s+[\d.]+ (cm|%)"
)
MAP_SIZE = re.compile(r"map ([\d.]+ MB)")
# Centimetres or percentage points: twice the spread measured between two hosts.
TOLERANCE = 0.05


def parsed(line: str):
    """(label, value, unit) of a metric line."""
    label, value, unit = re.match(r"^(.*?) ([\d.]+) (cm|%)", line).groups()
    return label, float(value), unit


def close(quoted: list, printed: list) -> bool:
    if len(quoted) != len(printed):
        return False
    for q, p in zip(quoted, printed):
        (ql, qv, qu), (pl, pv, pu) = parsed(q), parsed(p)
        if ql != pl or qu != pu or abs(qv - pv) > TOLERANCE + 1e-9:
            return False
    return True


def normalised(line: str) -> str:
    return " ".join(line.split())


def main() -> int:
    shine, readme_path, work = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
    out = work / "out"
    shutil.rmtree(out, ignore_errors=True)
    work.mkdir(parents=True, exist_ok=True)
    run = subprocess.run([shine, "map", "-o", str(out)], stdout=subprocess.PIPE,
                         stderr=subprocess.DEVNULL, text=True, check=False)
    if run.returncode != 0:
        print(run.stdout)
        print(f"shine map exited with {run.returncode}")
        return 1
    printed = [normalised(l) for l in run.stdout.splitlines() if METRIC_LINE.match(l)]
    map_size = MAP_SIZE.search(run.stdout)
    if len(printed) != 6 or map_size is None:
        print(run.stdout)
        print("the example's output no longer has the six metric lines and the map size")
        return 1
    figures = dict(re.match(r"^(.*?) ([\d.]+ (?:cm|%))", l).groups() for l in printed)

    readme = readme_path.read_text()
    block = re.search(r"<!-- example figures -->(.*?)<!-- /example figures -->", readme, re.S)
    if block is None:
        print(f"{readme_path} has no <!-- example figures --> block")
        return 1
    quoted = [normalised(l) for l in block.group(1).splitlines() if METRIC_LINE.match(l.strip())]
    failures = []
    if not close(quoted, printed):
        failures.append("the README's example block quotes\n  " + "\n  ".join(quoted) +
                        "\nbut the example prints\n  " + "\n  ".join(printed))

    rows = [l for l in readme.splitlines()
            if l.startswith("| bundled street") and "run_example.sh" in l]
    if len(rows) != 1:
        failures.append(f"expected one results row '| bundled street ... run_example.sh', "
                        f"found {len(rows)}")
    else:
        row = rows[0]
        if map_size.group(1) not in row:
            failures.append(f"the results row does not quote the printed {map_size.group(1)}: "
                            f"{row}")
        for label, pattern in (("accuracy", r"accuracy ([\d.]+) cm"), ("F-score", r"F ([\d.]+) %")):
            printed_value = float(figures[label].split()[0])
            found = re.search(pattern, row)
            if found is None or abs(float(found.group(1)) - printed_value) > TOLERANCE + 1e-9:
                failures.append(f"the results row does not quote the printed {label} "
                                f"{figures[label]} (within {TOLERANCE}): {row}")

    for failure in failures:
        print(failure)
    if not failures:
        print("README quotes the example's figures as printed: " + "; ".join(printed) +
              f"; map {map_size.group(1)}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
