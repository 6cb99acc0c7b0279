#!/usr/bin/env python3
"""Mean and spread of downstream rows over several runs of `uwnr experiment downstream`.

Usage: python3 tools/downstream_seeds.py [--versus ROW] RUN_DIR... (each holding a results.json;
typically the same command with --seed 0, 1, 2). A RUN_DIR written LABEL=DIR renames that run's rows
(all but the unenhanced input) to LABEL, so runs of one method with different settings (v4's
weights and v5's, both rows named uwnr) become separate rows. For every row name found in any run it prints,
per test set and metric, the mean over the runs that have the row, and the spread as the sample
standard deviation and the min-max range, with the number of runs behind it.

With --versus ROW it then prints, for every other row, its PSNR and SSIM minus ROW's, paired by
the experiment's seed: runs with the same seed draw the same references for each clean image and
start the enhancer from the same initial weights and crops, so the per-seed difference is freer
of noise than the difference of the means. Standard library only.
"""
import json
import statistics
import sys
from pathlib import Path

METRICS = ("psnr", "ssim", "uiqm", "uciqe")
DIGITS = {"psnr": 2, "ssim": 3, "uiqm": 3, "uciqe": 3}


def main(argv):
    args = argv[1:]
    versus = None
    if args[:1] == ["--versus"]:
        if len(args) < 2:
            print("error: --versus needs a row name", file=sys.stderr)
            return 2
        versus, args = args[1], args[2:]
    if not args:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    runs = []
    for arg in args:
        label, sep, d = arg.partition("=")
        if not sep or "/" in label:
            label, d = None, arg
        path = Path(d) / "results.json"
        try:
            run = json.loads(path.read_text())
        except (OSError, ValueError) as e:
            print(f"error: {path}: {e}", file=sys.stderr)
            return 1
        if label:
            for row in run["rows"]:
                if row["name"] != "none":
                    row["name"] = label
        runs.append((d, run))
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
                cells.append(spread([row["scores"][i][m] for row in rows], DIGITS[m]))
        print("| " + " | ".join(cells) + " |")
    if versus is not None:
        return print_paired(runs, tests, names, versus)
    return 0


def spread(v, k, signed=False):
    """`mean ± sd (min-max)` of a list, or the value alone for one; `signed` shows the signs of
    differences (and writes the range `min to max`)."""
    f = "+" if signed else ""
    if len(v) == 1:
        return f"{v[0]:{f}.{k}f}"
    sd = statistics.stdev(v)
    lo, hi = f"{min(v):{f}.{k}f}", f"{max(v):{f}.{k}f}"
    span = f"{lo} to {hi}" if signed else f"{lo}-{hi}"
    return f"{statistics.mean(v):{f}.{k}f} ± {sd:.{k}f} ({span})"


def print_paired(runs, tests, names, versus):
    """Per-seed differences of every row from `versus`, seeds paired by `settings.seed`."""
    by_seed = {}
    for _, r in runs:
        for row in r["rows"]:
            by_seed.setdefault(row["name"], {})[r["settings"]["seed"]] = row
    if versus not in by_seed:
        print(f"error: no row named {versus}", file=sys.stderr)
        return 1
    base = by_seed[versus]
    header = ["row", "seeds"] + [f"{t} {m}" for t in tests for m in ("psnr", "ssim")]
    print()
    print(f"Paired by seed: row minus {versus}")
    print()
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for name in names:
        if name == versus:
            continue
        seeds = sorted(set(by_seed[name]) & set(base))
        if not seeds:
            continue
        cells = [name, ",".join(str(s) for s in seeds)]
        for i, _ in enumerate(tests):
            for m in ("psnr", "ssim"):
                v = [
                    by_seed[name][s]["scores"][i][m] - base[s]["scores"][i][m]
                    for s in seeds
                ]
                cells.append(spread(v, DIGITS[m], signed=True))
        print("| " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
