#!/usr/bin/env python3
"""Example enhancements from several runs of `uwnr experiment downstream`, side by side.

Usage: python3 tools/downstream_examples.py OUT.jpg TEST_DIR... -- RUN_DIR...

Each RUN_DIR holds one or more trained rows (RUN_DIR/runs/NAME/checkpoints/last/
enhancer.safetensors, as `tools/run_downstream.sh` leaves them). For the first N pairs (sorted by
name) of each paired TEST_DIR (underwater/ and clean/), every row's network enhances the
underwater image, downscaled to at most 512 px as the experiment scores it, with `uwnr enhance
apply`; the figure shows, per pair, the input, one column per row (in the order given) and the
clean reference. This is the experiment's own examples.png for rows trained in separate runs
(one method and seed per run). Environment: BIN (default target/release/uwnr), DEVICE (default
flex), N (default 2), THUMB (thumbnail height, default 160). Needs Pillow.
"""
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

EXTS = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"}
MAX_SIDE = 512
GAP = 4


def images(d):
    return {p.stem: p for p in sorted(Path(d).iterdir()) if p.suffix.lower() in EXTS}


def fit(img, side):
    w, h = img.size
    s = side / max(w, h)
    return img.resize((round(w * s), round(h * s)), Image.LANCZOS) if s < 1 else img


def main(argv):
    if "--" not in argv or len(argv) < 5:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    cut = argv.index("--")
    out, tests, runs = Path(argv[1]), argv[2:cut], argv[cut + 1 :]
    binary = os.environ.get("BIN", "target/release/uwnr")
    device = os.environ.get("DEVICE", "flex")
    n = int(os.environ.get("N", "2"))
    thumb = int(os.environ.get("THUMB", "160"))
    rows = []  # (run label, weights)
    for run in runs:
        found = sorted(Path(run, "runs").glob("*/checkpoints/last/enhancer.safetensors"))
        if not found:
            print(f"error: no trained row in {run}/runs", file=sys.stderr)
            return 1
        for w in found:
            rows.append((w.parents[2].name, w))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        inputs = []  # (label, input path, clean image)
        for t in tests:
            uw, clean = images(Path(t, "underwater")), images(Path(t, "clean"))
            for name in [k for k in uw if k in clean][:n]:
                p = tmp / "in" / f"{len(inputs):02}-{name}.png"
                p.parent.mkdir(parents=True, exist_ok=True)
                fit(Image.open(uw[name]).convert("RGB"), MAX_SIDE).save(p)
                ref = fit(Image.open(clean[name]).convert("RGB"), MAX_SIDE)
                inputs.append((f"{Path(t).name}: {name}", p, ref))
        outputs = []
        for i, (label, w) in enumerate(rows):
            d = tmp / f"out{i}"
            subprocess.run(
                [binary, "enhance", "apply", "--weights", str(w), "--device", device,
                 "--output", str(d), str(tmp / "in")],
                check=True, stdout=subprocess.DEVNULL,
            )
            outputs.append(d)
        header = ["input"] + [f"trained on {label}" for label, _ in rows] + ["clean reference"]
        grid = []
        for k, (label, p, ref) in enumerate(inputs):
            cells = [Image.open(p).convert("RGB")]
            cells += [Image.open(d / f"{p.stem}.png").convert("RGB") for d in outputs]
            cells.append(ref)
            grid.append((label, [c.resize((round(c.width * thumb / c.height), thumb)) for c in cells]))
    font = ImageFont.load_default()
    cols = len(header)
    col_w = [max(max(r[1][c].width for r in grid), font.getbbox(header[c])[2] + 8) for c in range(cols)]
    label_w = max(font.getbbox(label)[2] for label, _ in grid) + 8
    head_h = 20
    width = label_w + sum(col_w) + GAP * (cols + 1)
    height = head_h + len(grid) * (thumb + GAP) + GAP
    sheet = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(sheet)
    x = label_w + GAP
    xs = []
    for c in range(cols):
        xs.append(x)
        tw = font.getbbox(header[c])[2]
        draw.text((x + (col_w[c] - tw) // 2, 4), header[c], fill="black", font=font)
        x += col_w[c] + GAP
    for r, (label, cells) in enumerate(grid):
        y = head_h + GAP + r * (thumb + GAP)
        draw.text((4, y + thumb // 2 - 6), label, fill="black", font=font)
        for c, img in enumerate(cells):
            sheet.paste(img, (xs[c] + (col_w[c] - img.width) // 2, y))
    tmp_out = out.with_name(out.name + ".tmp" + out.suffix)
    sheet.save(tmp_out, quality=90)
    os.replace(tmp_out, out)
    print(f"wrote {out} ({len(grid)} pairs x {len(rows)} networks)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
