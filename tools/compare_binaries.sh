#!/usr/bin/env bash
# Do two `uwnr` binaries make the same datasets? For every render method, `uwnr dataset` on the
# same clean photos (Set14 at native sizes, so odd sizes and tiling-free whole images; plus two
# SUN photos at 1024 px) and references (U45), K = 2, once as image folders and once as
# WebDataset shards; then `cmp` of every file (of every shard member, in order). Used when code moves between crates (the render
# wing's split from burn): the outputs must not change, or the differences are listed.
#   OLD=path/to/old/uwnr NEW=target/release/uwnr [PYTHON=venv/bin/python] bash tools/compare_binaries.sh
# (PYTHON needs numpy and pillow, to measure how far differing images are apart.)
# Run from the repository root with ../shared/data present. Prints one line per method and
# format, and the files that differ with the largest per-pixel difference of the images.
set -euo pipefail
DATA=${DATA:-../shared/data}
OLD=${OLD:?the old binary}
NEW=${NEW:-target/release/uwnr}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$WORK/clean"
cp "$DATA"/inair/set14/*.jpg "$WORK/clean/"
suns=("$DATA"/inair/sun-hays80/*.jpg)
cp "${suns[@]:0:2}" "$WORK/clean/"
REFS="$DATA/references/u45"
status=0
for method in ${METHODS:-uwnr uwgan jerlov uisa seathru reinhard haze}; do
  for format in folder webdataset; do
    extra=()
    if [ "$format" = webdataset ]; then extra=(--format webdataset); fi
    for which in old new; do
      bin=$OLD; [ "$which" = new ] && bin=$NEW
      "$bin" dataset --clean "$WORK/clean" --references "$REFS" --method "$method" \
        --output "$WORK/$method-$format-$which" --per-image 2 --seed 7 --no-gallery \
        "${extra[@]}" > "$WORK/$method-$format-$which.log" 2>&1 || {
        echo "$method $format $which: failed"; tail -3 "$WORK/$method-$format-$which.log"; status=1; }
    done
    a="$WORK/$method-$format-old" b="$WORK/$method-$format-new"
    # Shards are compared by their members (name, then contents): the tar headers' own bytes
    # changed with the `tar` crate (docs/datasets.md, WebDataset); set RAW_TARS=1 to compare them as bytes.
    if [ "$format" = webdataset ] && [ -z "${RAW_TARS:-}" ]; then
      for d in "$a" "$b"; do
        for t in "$d"/webdataset/*.tar; do
          mkdir -p "$t.members" && tar -xf "$t" -C "$t.members" && tar -tf "$t" > "$t.names" && rm "$t"
        done
      done
    fi
    n=$(cd "$a" && find . -type f | wc -l)
    diffs=$(cd "$a" && find . -type f | sort | while read -r f; do
      cmp -s "$f" "$b/$f" || echo "$f"; done)
    if [ -z "$diffs" ] && [ "$n" = "$(cd "$b" && find . -type f | wc -l)" ]; then
      echo "$method $format: $n files, byte-identical"
    else
      echo "$method $format: $(echo "$diffs" | grep -c .) of $n files differ"
      echo "$diffs" | grep -v '\.png$' | sed 's/^/  /'
      # How far apart the differing images are, in 8-bit levels.
      echo "$diffs" | grep '\.png$' | "${PYTHON:-python3}" -c '
import sys
import numpy as np
from PIL import Image
a, b = sys.argv[1], sys.argv[2]
worst, pixels, total = 0, 0, 0
for f in sys.stdin.read().split():
    x = np.asarray(Image.open(a + "/" + f), dtype=np.int32)
    y = np.asarray(Image.open(b + "/" + f), dtype=np.int32)
    d = np.abs(x - y)
    worst = max(worst, int(d.max()))
    pixels += int((d.max(axis=-1) > 0).sum())
    total += d.shape[0] * d.shape[1]
print(f"  images: largest difference {worst} level(s), {pixels} of {total} pixels differ")
' "$a" "$b"
      status=1
    fi
  done
done
exit $status
