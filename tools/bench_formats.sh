#!/usr/bin/env bash
# The folder layout against WebDataset shards on the same set: 168 in-air photos (CBSD68 and
# Urban100) at --size 256x256, K = 2 (336 pairs), references from references/u45, METHOD
# (default uwnr, the bundled model).
#   1. `uwnr dataset` with --format folder, then the same command with --format webdataset in
#      another folder (rendering plus packing), and `uwnr dataset export` of the first folder alone;
#   2. copying each layout to another folder (what moving it to a cluster costs in files);
#   3. reading every pair in Python (tools/bench_formats_read.py): loose files vs the shards
#      streamed by the `webdataset` package, as raw bytes and decoded to arrays.
# Run from the repository root with ../shared/data present, on a quiet machine:
#   cargo build --release -p uwnr-cli && bash tools/bench_formats.sh
# PYTHON must have webdataset and pillow (pip install webdataset pillow).
set -euo pipefail
DATA=${DATA:-../shared/data}
BIN=${BIN:-target/release/uwnr}
PYTHON=${PYTHON:-python3}
METHOD=${METHOD:-uwnr}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

mkdir -p "$WORK/clean"
cp "$DATA"/inair/cbsd68/*.jpg "$DATA"/inair/urban100/*.jpg "$WORK/clean/"
REFS="$DATA/references/u45"
ARGS=(--clean "$WORK/clean" --references "$REFS" --per-image 2 --size 256x256 --method "$METHOD"
  --no-gallery --seed 1)

secs() { # command... -> wall seconds
  local t0 t1
  t0=$(date +%s.%N)
  "$@" > /dev/null 2>&1
  t1=$(date +%s.%N)
  echo "$t1 - $t0" | bc
}
pairs=$(( $(ls "$WORK/clean" | wc -l) * 2 ))
echo "pairs: $pairs"
t=$(secs "$BIN" dataset "${ARGS[@]}" --output "$WORK/folder")
echo "generate --format folder:      $t s ($(echo "scale=2; $pairs / $t" | bc) pairs/s)"
t=$(secs "$BIN" dataset "${ARGS[@]}" --output "$WORK/wds" --format webdataset)
echo "generate --format webdataset:  $t s ($(echo "scale=2; $pairs / $t" | bc) pairs/s)"
t=$(secs "$BIN" dataset export "$WORK/folder" --to "$WORK/exported")
echo "export alone:                  $t s"
cmp <(cat "$WORK"/exported/*.tar) <(cat "$WORK"/wds/webdataset/*.tar) && echo "export = packed shards: identical bytes"
echo "files: folder $(find "$WORK/folder" -type f | wc -l), shards $(ls "$WORK"/wds/webdataset | wc -l);" \
  "bytes: folder $(du -sb "$WORK/folder" | cut -f1), shards $(du -sb "$WORK/wds/webdataset" | cut -f1)"
sync
t=$(secs cp -r "$WORK/folder" "$WORK/copy-folder")
echo "copy folder:                   $t s"
t=$(secs cp -r "$WORK/wds/webdataset" "$WORK/copy-shards")
echo "copy shards:                   $t s"
"$PYTHON" tools/bench_formats_read.py "$WORK/folder" "$WORK/wds"
