"""Reads every pair of a dataset folder and of its WebDataset shards (same pairs), as raw bytes and
decoded to arrays with Pillow, and prints pairs/s for each (best of 3). Used by
tools/bench_formats.sh:  python tools/bench_formats_read.py FOLDER_DATASET WDS_DATASET"""

import io
import json
import os
import sys
import time

import numpy as np
import webdataset as wds
from PIL import Image


def folder_pairs(root, decode):
    with open(os.path.join(root, "manifest.jsonl")) as f:
        records = [json.loads(line) for line in f]
    n = 0
    for r in records:
        for key in ("underwater", "clean"):
            with open(os.path.join(root, r[key]), "rb") as g:
                data = g.read()
            if decode:
                np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
        n += 1
    return n


def shard_pairs(root, decode):
    with open(os.path.join(root, "webdataset", "index.json")) as f:
        urls = [os.path.join(root, "webdataset", s["file"]) for s in json.load(f)["shards"]]
    n = 0
    for sample in wds.WebDataset(urls, shardshuffle=False, empty_check=False):
        json.loads(sample["json"])
        for key in ("underwater.png", "clean.png"):
            if decode:
                np.asarray(Image.open(io.BytesIO(sample[key])).convert("RGB"))
        n += 1
    return n


def best(fn, *args):
    times = []
    for _ in range(3):
        t = time.perf_counter()
        n = fn(*args)
        times.append(time.perf_counter() - t)
    return n / min(times), n


def main():
    folder, shards = sys.argv[1], sys.argv[2]
    for decode in (False, True):
        what = "decoded" if decode else "raw bytes"
        rate, n = best(folder_pairs, folder, decode)
        print(f"read {what:9s} folder: {rate:8.1f} pairs/s ({n} pairs)")
        rate, n = best(shard_pairs, shards, decode)
        print(f"read {what:9s} shards: {rate:8.1f} pairs/s ({n} pairs)")


if __name__ == "__main__":
    main()
