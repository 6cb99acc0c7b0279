#!/usr/bin/env python3
"""Dark stays dark: how far `±1` code value of noise on a photo moves its render.

For the four darkest photos of `inair/` and a synthetic dusk photo (a dark sky gradient with a
bright rocket and plume), each photo and a copy with ±1 of seeded noise on every value are
rendered after three references (U45, RUIE green, UIEB challenging) with the default model
(extra arguments go to `uwnr render`, e.g. `--weights FILE`), Reinhard and UISA; prints the
largest change of any value, in code values, per photo and method.

Run from the repository root: python3 tools/dark_noise.py [uwnr render args...]
(needs numpy and Pillow; BIN and DATA as in the shell tools)
"""
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

BIN = os.environ.get("BIN", "target/release/uwnr")
DATA = Path(os.environ.get("DATA", "../shared/data"))


def dusk(path):
    h, w = 240, 320
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([8 + 10 * y / h, 6 + 8 * y / h, 14 + 12 * y / h], -1)
    rocket = (abs(x - 160) < 8) & (y > 60) & (y < 170)
    plume = ((x - 160) ** 2 / 30**2 + (y - 195) ** 2 / 40**2) < 1
    img[rocket] = [200, 200, 210]
    img[plume] = [255, 210, 120]
    Image.fromarray(img.clip(0, 255).astype(np.uint8)).save(path)


def main():
    tmp = Path(tempfile.mkdtemp())
    photos = sorted(p for p in (DATA / "inair").glob("*/*.jpg"))
    brightness = sorted((np.asarray(Image.open(p).convert("L"), dtype=np.float32).mean(), p) for p in photos)
    chosen = [p for _, p in brightness[:4]]
    dusk(tmp / "dusk.png")
    chosen.append(tmp / "dusk.png")
    challenging = sorted((DATA / "references/uieb-challenging").iterdir())[0]
    refs = [DATA / "references/u45/U45/10.png", DATA / "references/ruie-uccs/green/green_21.jpg", challenging]
    methods = [("uwnr", sys.argv[1:]), ("reinhard", ["--method", "reinhard"]), ("uisa", ["--method", "uisa"])]
    rng = np.random.default_rng(0)
    print("photo | mean level | " + " | ".join(m for m, _ in methods))
    for f in chosen:
        a = np.asarray(Image.open(f).convert("RGB"), dtype=np.int16)
        n = (a + rng.choice([-1, 1], a.shape)).clip(0, 255).astype(np.uint8)
        Image.fromarray(a.astype(np.uint8)).save(tmp / "a.png")
        Image.fromarray(n).save(tmp / "n.png")
        row = [f.name, f"{a.mean():.0f}"]
        for _, args in methods:
            worst = 0
            for r in refs:
                for src, out in [("a.png", "ra.png"), ("n.png", "rn.png")]:
                    subprocess.run([BIN, "render", str(tmp / src), "--reference", str(r), "-o", str(tmp / out), "--seed", "1"] + args,
                                   check=True, capture_output=True)
                d = np.abs(np.asarray(Image.open(tmp / "ra.png"), dtype=np.int16) - np.asarray(Image.open(tmp / "rn.png"), dtype=np.int16))
                worst = max(worst, int(d.max()))
            row.append(str(worst))
        print(" | ".join(row))


if __name__ == "__main__":
    main()
