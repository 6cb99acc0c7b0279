#!/usr/bin/env python3
"""Mean and spread of downstream rows over several runs of `uwnr experiment downstream`.

Usage: python3 tools/downstream_seeds.py RUN_DIR... (each holding a results.json; typically the
same command with --seed 0, 1, 2). For every row name found in any run it prints, per test set
and metric, the mean over the runs that have the row, and the spread as the sample standard
deviation and the min-max range, with the number of runs behind it. Standard library only.
"""
import json
import statistics
import sys
from pathlib import Path

METRICS = ("psnr", "ssim", "uiqm", "uciqe")
DIGITS = {"psnr": 2, "ssim": 3, "uiqm": 3, "uciqe": 3}


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    runs = []
    for d in argv[1:]:
        path = Path(d) / "results.json"
        try:
            runs.append((d, json.loads(path.read_text())))
        except (OSError, ValueError) as e:
            print(f"error: {path}: {e}", file=sys.stderr)
            return 1
    tests = [t["name"] for t in runs[0][1]["tests"]]
    for d, r in runs[1:]:
        if [t["name"] for t in r["tests"]] != tests:
            print(f"error: {d} was scored on other test sets", file=sys.stderr)
            return 1
    names = []
    for _, r in runs:
        for row in r["rows"]:
            if row["name"] not in names:
                names.append(row["name"])
    header = ["row", "runs"] + [f"{t} {m}" for t in tests for m in METRICS]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for name in names:
        rows = [row for _, r in runs for row in r["rows"] if row["name"] == name]
        cells = [name, str(len(rows))]
        for i, _ in enumerate(tests):
            for m in METRICS:
                v = [row["scores"][i][m] for row in rows]
                k = DIGITS[m]
                if len(v) == 1:
                    cells.append(f"{v[0]:.{k}f}")
                else:
                    sd = statistics.stdev(v)
                    cells.append(
                        f"{statistics.mean(v):.{k}f} ± {sd:.{k}f} ({min(v):.{k}f}-{max(v):.{k}f})"
                    )
        print("| " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
