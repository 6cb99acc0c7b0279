#!/usr/bin/env python3
"""Whether a dataset's colour cast points at its references' colour.

For every pair of a `uwnr dataset` folder: the cast is the chroma of the mean colour change,
mean(underwater) - mean(clean) with its grey part (the mean of the three channels) removed; the
reference's colour is the chroma of its mean colour, mean(reference) with its grey part removed.
Prints the mean cosine between the two (1: the cast always points at the reference's colour,
0: unrelated) and the mean chroma shift of the pairs towards the reference's (a projection
scaled by the reference's own chroma: 1 = the pair takes on the reference's whole cast, 0 = none;
a pure Reinhard transfer of a grey-world photo scores about 1).

Usage: python3 tools/pair_cast.py DATASET_DIR [...]   (needs numpy and Pillow)
"""
import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image


def mean_rgb(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64).reshape(-1, 3).mean(0) / 255.0


def chroma(v):
    return v - v.mean()


def main():
    for folder in map(Path, sys.argv[1:]):
        cos, take = [], []
        ref_cache = {}
        for line in (folder / "manifest.jsonl").read_text().splitlines():
            r = json.loads(line)
            ref = r.get("reference_source")
            if not ref:
                continue
            if ref not in ref_cache:
                ref_cache[ref] = chroma(mean_rgb(ref))
            rc = ref_cache[ref]
            shift = chroma(mean_rgb(folder / r["underwater"]) - mean_rgb(folder / r["clean"]))
            n1, n2 = np.linalg.norm(shift), np.linalg.norm(rc)
            if n1 < 1e-6 or n2 < 1e-6:
                continue
            cos.append(float(shift @ rc / (n1 * n2)))
            take.append(float(shift @ rc / (n2 * n2)))
        if cos:
            print(f"{folder}\tpairs {len(cos)}\tcast cosine {np.mean(cos):.3f}\tshare of the reference's cast {np.mean(take):.3f}")
        else:
            print(f"{folder}\tno pairs with a reference")


if __name__ == "__main__":
    main()
