#!/usr/bin/env python3
"""A side-by-side sheet of datasets made from the same clean images, references and seed
(tools/strength_table.sh makes them): per row a pair's clean image, its reference, then each
dataset's render of that pair, labelled with the pair's PSNR(underwater, clean).

Usage: python3 tools/side_by_side.py OUT.jpg ROWS NAME=DATASET_DIR [...]   (needs Pillow)
"""
import json
import sys
from pathlib import Path

from PIL import Image, ImageDraw

THUMB = 160
LABEL = 16


def main():
    out, rows, sets = sys.argv[1], int(sys.argv[2]), [a.split("=", 1) for a in sys.argv[3:]]
    manifests = []
    for _, d in sets:
        lines = [json.loads(line) for line in (Path(d) / "manifest.jsonl").read_text().splitlines()]
        manifests.append({r["id"]: r for r in lines})
    ids = sorted(manifests[0])[: rows * 7 : 7][:rows]
    cols = 2 + len(sets)
    sheet = Image.new("RGB", (cols * THUMB, LABEL + rows * (THUMB + LABEL)), "white")
    draw = ImageDraw.Draw(sheet)
    for c, title in enumerate(["clean", "reference"] + [n for n, _ in sets]):
        draw.text((c * THUMB + 4, 2), title, fill="black")
    for r, pid in enumerate(ids):
        y = LABEL + r * (THUMB + LABEL)
        first = manifests[0][pid]
        base = Path(sets[0][1])
        tiles = [(base / first["clean"], ""), (Path(first["reference_source"]), "")]
        for (name, d), m in zip(sets, manifests):
            rec = m[pid]
            tiles.append((Path(d) / rec["underwater"], f'{rec.get("strength_db", float("nan")):.1f} dB'))
        for c, (path, label) in enumerate(tiles):
            img = Image.open(path).convert("RGB")
            img.thumbnail((THUMB, THUMB))
            sheet.paste(img, (c * THUMB, y))
            if label:
                draw.text((c * THUMB + 4, y + THUMB + 1), label, fill="black")
    sheet.save(out, quality=90)


if __name__ == "__main__":
    main()
