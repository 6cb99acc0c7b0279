#!/usr/bin/env bash
# The strength of every method's pairs, PSNR(underwater, clean), as `uwnr dataset` reports it,
# and whether each pair's cast points at its reference's colour (tools/pair_cast.py): the clean
# images of inair/cbsd68 and inair/set14, 2 renders each at 256x256, seed 0, with the RUIE and
# U45 references (REFS=ruie) or UIEB's challenging photos (REFS=uieb). Real pairs for
# comparison: `uwnr water fit` prints their strengths.
# CAMERA sets `--camera` (e.g. '{"clean":"none"}'); unset, `uwnr dataset`'s default.
# METHOD_CONFIG gives uwnr a `--method-config` file (NAME names its rows; default the file's name).
# Run from the repository root: bash tools/strength_table.sh [BIN]   (PYTHON: with numpy, Pillow)
set -euo pipefail
BIN=${1:-${BIN:-target/release/uwnr}}
DATA=${DATA:-../shared/data}
OUT=${OUT:-../uwnr-runs/strength}
PYTHON=${PYTHON:-python3}
METHODS=${METHODS:-uwnr uisa seathru reinhard jerlov uwgan}
case ${REFS:-ruie} in
  ruie) R=("$DATA/references/ruie-uccs" "$DATA/references/ruie-uiqs-a" "$DATA/references/u45") ;;
  uieb) R=("$DATA/references/uieb-challenging") ;;
  *) echo "REFS is ruie or uieb" >&2; exit 1 ;;
esac
mkdir -p "$OUT"
for m in $METHODS; do
  name=$m${WEIGHTS:+-$(basename "$WEIGHTS" .safetensors)}
  C=()
  if [ "$m" = uwnr ] && [ -n "${METHOD_CONFIG:-}" ]; then
    C=(--method-config "$METHOD_CONFIG")
    name=$m-${NAME:-$(basename "$METHOD_CONFIG" .json)}
  fi
  dir="$OUT/${REFS:-ruie}-$name"
  W=()
  [ "$m" = uwnr ] && [ -n "${WEIGHTS:-}" ] && W=(--weights "$WEIGHTS")
  line=$("$BIN" dataset --clean "$DATA/inair/cbsd68" "$DATA/inair/set14" --references "${R[@]}" \
    -k 2 --size 256x256 --seed 0 --method "$m" "${W[@]}" "${C[@]}" ${CAMERA:+--camera "$CAMERA"} --no-gallery -o "$dir" 2>&1 | grep '^strength' || true)
  cast=$("$PYTHON" tools/pair_cast.py "$dir" | cut -f3-)
  printf '%s\t%s\t%s\n' "$name" "${line#strength PSNR(underwater, clean) over }" "$cast"
done
