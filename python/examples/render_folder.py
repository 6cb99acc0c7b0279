"""Renders every photo of a folder as an underwater image in the style of references drawn from
another folder, with a progress bar (tqdm when installed).

    python render_folder.py CLEAN_DIR REFERENCE_DIR OUT_DIR [--method uwnr] [--seed 0]

Each output is written to a temporary file and renamed, so an interrupted run leaves no partial
image; files that fail are listed at the end and the exit status is 1.
"""

import argparse
import os
import sys

import numpy as np
from PIL import Image

import uwnr

EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def images(folder):
    return sorted(os.path.join(folder, f) for f in os.listdir(folder) if f.lower().endswith(EXTENSIONS))


def progress(items):
    try:
        from tqdm import tqdm

        return tqdm(items, unit="image")
    except ImportError:
        def plain(seq):
            for i, item in enumerate(seq, 1):
                print(f"\r{i}/{len(seq)}", end="", file=sys.stderr, flush=True)
                yield item
            print(file=sys.stderr)

        return plain(items)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clean_dir")
    ap.add_argument("reference_dir")
    ap.add_argument("out_dir")
    ap.add_argument("--method", default="uwnr", choices=uwnr.METHODS)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    cleans, refs = images(args.clean_dir), images(args.reference_dir)
    if not cleans or not refs:
        sys.exit("uwnr: both folders must hold images")
    os.makedirs(args.out_dir, exist_ok=True)
    renderer = uwnr.Renderer(method=args.method, seed=args.seed)
    references = {}  # each reference decoded, and its light field computed, once
    rng = np.random.default_rng(args.seed)
    failed = []
    for index, path in enumerate(progress(cleans)):
        ref_path = refs[int(rng.integers(len(refs)))]
        try:
            if ref_path not in references:
                references[ref_path] = uwnr.Reference(ref_path)
            out = renderer.render(path, references[ref_path], index=index)
            name = os.path.splitext(os.path.basename(path))[0] + ".png"
            target = os.path.join(args.out_dir, name)
            tmp = target + ".tmp"
            Image.fromarray(out).save(tmp, format="PNG")
            os.replace(tmp, target)
        except (ValueError, OSError, uwnr.Error) as e:
            failed.append(f"{path}: {e}")
    for line in failed:
        print(f"failed: {line}", file=sys.stderr)
    print(f"rendered {len(cleans) - len(failed)} of {len(cleans)} images into {args.out_dir}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
