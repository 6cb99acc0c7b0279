#!/usr/bin/env bash
# Scores a model on paired/uieb-val exactly as MODEL_CARD.md reports it, beside the simple
# baselines computed the same way. Each clean image is rendered with its own real underwater
# image as the reference (same file names, so `--pairing cycle` pairs them), at its native size,
# and the render is scored against that underwater image with `uwnr eval` (scikit-image PSNR and
# SSIM on RGB, data range 1, means over the 33 pairs).
#   identity     the clean image as is
#   mean shift   per-channel RGB mean shift to the underwater image
#   reinhard     Reinhard colour transfer in CIELAB (and in the paper's lαβ)
#   model        the network (the bundled model, or WEIGHTS=FILE)
# Run from the repository root: bash tools/eval_default_model.sh [BIN]
set -euo pipefail
BIN=${1:-${BIN:-target/release/uwnr}}
DATA=${DATA:-../shared/data}
VAL="$DATA/paired/uieb-val"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
W=()
if [ -n "${WEIGHTS:-}" ]; then W=(--weights "$WEIGHTS"); fi

score() { # name, prediction folder
  local mean
  mean=$("$BIN" eval --pred "$2" --target "$VAL/underwater" 2>/dev/null | grep '^mean')
  printf '%-22s %s\n' "$1" "$mean"
}
render() { # folder, extra args...
  local out=$1
  shift
  "$BIN" render "$VAL/clean" --reference "$VAL/underwater" --pairing cycle --output "$out" \
    "$@" 2>/dev/null
}
"$BIN" eval --pred "$VAL/clean" --target "$VAL/underwater" 2>/dev/null | head -1 | sed 's/^image/                       /'
score identity "$VAL/clean"
render "$WORK/meanshift" --method reinhard --reinhard-space rgb --mean-only
score "mean shift (RGB)" "$WORK/meanshift"
render "$WORK/reinhard-lab" --method reinhard --reinhard-space lab
score "Reinhard (CIELAB)" "$WORK/reinhard-lab"
render "$WORK/reinhard-lab-paper" --method reinhard
score "Reinhard (lαβ)" "$WORK/reinhard-lab-paper"
render "$WORK/model" "${W[@]}"
score "model" "$WORK/model"
