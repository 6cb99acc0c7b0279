#!/usr/bin/env python3
"""Pairs for training the correction for realism (`uwnr train` with `config.adversarial`):
each clean photo beside K real underwater photos of other scenes, as a paired folder
(`clean/NAME__k.png`, `underwater/NAME__k.png`). The trainer reads each underwater photo as a
render reads its reference (its light field and water) and shows it to the discriminator as a
real photo; no pixel of it is a target.

Both sides are centre-cropped to a square and resized to SIZE (Lanczos). References are drawn
per clean photo without replacement from a generator seeded by SEED. Needs Pillow.

    python3 tools/realism_pairs.py OUT --clean DIR [DIR ...] --references DIR [DIR ...] \
        [-k 4] [--size 256] [--seed 0]

The folder is written beside OUT and renamed into place when complete.
"""

import argparse
import os
import random
import shutil
import sys

from PIL import Image

EXTS = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


def images(dirs):
    out = []
    for d in dirs:
        for root, _, files in os.walk(d):
            out += [os.path.join(root, f) for f in files if os.path.splitext(f)[1].lower() in EXTS]
    return sorted(out)


def square(path, size):
    im = Image.open(path).convert("RGB")
    w, h = im.size
    s = min(w, h)
    x0, y0 = (w - s) // 2, (h - s) // 2
    return im.crop((x0, y0, x0 + s, y0 + s)).resize((size, size), Image.LANCZOS)


def name_of(path, roots):
    for r in roots:
        rel = os.path.relpath(path, r)
        if not rel.startswith(".."):
            stem = os.path.splitext(rel)[0]
            return f"{os.path.basename(os.path.normpath(r))}__{stem}".replace(os.sep, "__")
    return os.path.splitext(os.path.basename(path))[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--clean", nargs="+", required=True)
    ap.add_argument("--references", nargs="+", required=True)
    ap.add_argument("-k", type=int, default=4)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    clean, refs = images(a.clean), images(a.references)
    if not clean or not refs:
        sys.exit(f"error: {len(clean)} clean photos and {len(refs)} references found")
    if a.k < 1 or a.k > len(refs):
        sys.exit(f"error: -k {a.k} must be between 1 and the {len(refs)} references")
    if os.path.exists(a.out):
        sys.exit(f"error: {a.out} exists")
    tmp = a.out.rstrip("/") + ".partial"
    shutil.rmtree(tmp, ignore_errors=True)
    for d in ("clean", "underwater"):
        os.makedirs(os.path.join(tmp, d))
    rng = random.Random(a.seed)
    ref_cache = {}
    lines = []
    for c in clean:
        base = name_of(c, a.clean)
        im = square(c, a.size)
        for k, r in enumerate(rng.sample(refs, a.k)):
            name = f"{base}__{k}.png"
            im.save(os.path.join(tmp, "clean", name))
            if r not in ref_cache:
                ref_cache[r] = square(r, a.size)
            ref_cache[r].save(os.path.join(tmp, "underwater", name))
            lines.append(f"{name}\t{os.path.relpath(c)}\t{os.path.relpath(r)}\n")
    with open(os.path.join(tmp, "pairs.tsv"), "w") as f:
        f.writelines(lines)
    os.rename(tmp, a.out)
    print(f"{len(lines)} pairs of {len(clean)} clean photos and {len(ref_cache)} references in {a.out}")


if __name__ == "__main__":
    main()
