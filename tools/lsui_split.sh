#!/usr/bin/env bash
# Splits paired/lsui into a training part and a held-out test part by the committed list
# assets/splits/lsui-test.txt (27 of the 108 pairs: every 4th name in sorted order, fixed once).
# Makes OUT/lsui-train and OUT/lsui-test, each with clean/ and underwater/ holding symbolic
# links to the original files, so `uwnr train --data OUT/lsui-train` never sees a test pair.
# Usage, from the repository root: bash tools/lsui_split.sh [OUT]   (default ../uwnr-splits)
set -euo pipefail
DATA=${DATA:-../shared/data}
OUT=${1:-../uwnr-splits}
SRC="$DATA/paired/lsui"
LIST=assets/splits/lsui-test.txt
[ -d "$SRC/underwater" ] || { echo "error: $SRC/underwater not found" >&2; exit 1; }
SRC=$(cd "$SRC" && pwd)
for part in lsui-train lsui-test; do
  rm -rf "$OUT/$part"
  mkdir -p "$OUT/$part/clean" "$OUT/$part/underwater"
done
declare -A test
while read -r name; do [ -n "$name" ] && test[$name]=1; done < "$LIST"
n_train=0 n_test=0
for f in "$SRC"/underwater/*; do
  name=$(basename "$f")
  [ -e "$SRC/clean/$name" ] || continue
  if [ -n "${test[$name]:-}" ]; then part=lsui-test; n_test=$((n_test + 1)); else part=lsui-train; n_train=$((n_train + 1)); fi
  ln -s "$SRC/underwater/$name" "$OUT/$part/underwater/$name"
  ln -s "$SRC/clean/$name" "$OUT/$part/clean/$name"
done
if [ "$n_test" -ne "${#test[@]}" ]; then
  echo "error: $LIST names ${#test[@]} pairs, $n_test found in $SRC" >&2
  exit 1
fi
echo "lsui-train: $n_train pairs, lsui-test: $n_test pairs, in $OUT"
