#!/usr/bin/env python3
"""Whether a pair's two sides share the scene's light from above.

For every pair: log(mean luminance of the top third / mean luminance of the bottom third), at
128 x 128 px, of the underwater side and of the clean side, and their difference. Real pairs keep
the light on both sides (the difference is near 0); pairs lit on the underwater side only do not
(docs/RESULTS.md, "The lit clean side").

Usage: python3 tools/pair_light.py NAME,UNDERWATER_DIR,CLEAN_DIR [...]   (needs numpy and Pillow)
A clean image is matched to its underwater image by file name, or by stem with another extension.
"""
import sys
from pathlib import Path

import numpy as np
from PIL import Image


def top_over_bottom(path):
    lum = np.asarray(Image.open(path).convert("RGB").resize((128, 128)), dtype=np.float64).mean(2) + 1
    third = lum.shape[0] // 3
    return np.log(lum[:third].mean() / lum[-third:].mean())


def pairs(underwater, clean):
    out = []
    for u in sorted(Path(underwater).iterdir()):
        c = Path(clean) / u.name
        if not c.exists():
            found = sorted(Path(clean).glob(u.stem + ".*"))
            if not found:
                continue
            c = found[0]
        out.append((top_over_bottom(u), top_over_bottom(c)))
    return np.array(out)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for arg in sys.argv[1:]:
        name, underwater, clean = arg.split(",")
        x = pairs(underwater, clean)
        if len(x) == 0:
            print(f"{name}\tno pairs")
            continue
        d = x[:, 0] - x[:, 1]
        print(f"{name}\tn={len(x)}\tunderwater {x[:, 0].mean():+.3f}\tclean {x[:, 1].mean():+.3f}"
              f"\tunderwater minus clean {d.mean():+.3f} (sd {d.std():.3f})")


if __name__ == "__main__":
    main()
