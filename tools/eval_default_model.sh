#!/usr/bin/env bash
# Scores a model by self-reconstruction, as MODEL_CARD.md reports it, beside the simple and
# physical baselines computed the same way. Each clean image is rendered with its own real
# underwater image as the reference (same file names, so `--pairing cycle` pairs them), at its
# native size with the built-in depth prior, and the render is scored against that underwater
# image with `uwnr eval` (scikit-image PSNR and SSIM on RGB, data range 1, means over the pairs).
#   identity       the clean image as is
#   mean shift     per-channel RGB mean shift to the underwater image
#   reinhard       Reinhard colour transfer in CIELAB and in the paper's lαβ
#   uisa, seathru  the physical baselines with parameters read off the reference
#   model          the network (the bundled model, or WEIGHTS=FILE)
# Sets: SETS (default "uieb-val lsui-test"): uieb-val is paired/uieb-val, lsui-test the held-out
# part of paired/lsui (tools/lsui_split.sh makes it in SPLITS, default ../uwnr-splits).
# Run from the repository root: bash tools/eval_default_model.sh [BIN]
# BASELINES=0 scores the model only.
set -euo pipefail
BIN=${1:-${BIN:-target/release/uwnr}}
DATA=${DATA:-../shared/data}
SPLITS=${SPLITS:-../uwnr-splits}
SETS=${SETS:-uieb-val lsui-test}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
W=()
if [ -n "${WEIGHTS:-}" ]; then W=(--weights "$WEIGHTS"); fi

for set in $SETS; do
  case $set in
    lsui-test)
      [ -d "$SPLITS/lsui-test" ] || bash tools/lsui_split.sh "$SPLITS" >/dev/null
      VAL="$SPLITS/lsui-test" ;;
    *) VAL="$DATA/paired/$set" ;;
  esac
  n=$(ls "$VAL/underwater" | wc -l)
  echo "== $set ($n pairs)"
  score() { # name, prediction folder
    local mean
    mean=$("$BIN" eval --pred "$2" --target "$VAL/underwater" 2>/dev/null | grep '^mean')
    printf '%-22s %s\n' "$1" "$mean"
  }
  render() { # folder, extra args...
    local out=$1
    shift
    "$BIN" render "$VAL/clean" --reference "$VAL/underwater" --pairing cycle --output "$out" \
      "$@" >/dev/null 2>&1
  }
  "$BIN" eval --pred "$VAL/clean" --target "$VAL/underwater" 2>/dev/null | sed -n '1s/^image/                       /p'
  if [ "${BASELINES:-1}" = 1 ]; then
    score identity "$VAL/clean"
    render "$WORK/$set-meanshift" --method reinhard --reinhard-space rgb --mean-only
    score "mean shift (RGB)" "$WORK/$set-meanshift"
    render "$WORK/$set-reinhard-lab" --method reinhard --reinhard-space lab
    score "Reinhard (CIELAB)" "$WORK/$set-reinhard-lab"
    render "$WORK/$set-reinhard" --method reinhard
    score "Reinhard (lαβ)" "$WORK/$set-reinhard"
    render "$WORK/$set-uisa" --method uisa
    score "UISA" "$WORK/$set-uisa"
    render "$WORK/$set-seathru" --method seathru --seathru reference
    score "Sea-thru (fitted)" "$WORK/$set-seathru"
  fi
  render "$WORK/$set-model" "${W[@]}"
  score "model" "$WORK/$set-model"
done
