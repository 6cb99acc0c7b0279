#!/usr/bin/env bash
# The ablation table of MODEL_CARD.md: the bundled model's recipe (tools/train_default_model.json)
# with one lever changed at a time, each trained by tools/train_default_model.sh in its own run
# folder and scored by self-reconstruction on uieb-val and lsui-test (tools/eval_default_model.sh,
# the last checkpoint, model rows only). Usage, from the repository root:
#   bash tools/ablate_default_model.sh [VARIANT...]     (default: all of them)
# Variants (a JSON object merged into the recipe; nested objects merged key by key):
#   recipe        the recipe as it is
#   untrained     no training: one step at learning rate 1e-12 (the correction stays at zero)
#   no-detail     without detail retention (the v3 pipeline)
#   ssim-2        the SSIM term (the VGG19 stand-in) at weight 2 instead of 0.5
#   l1-only       no stand-in for the perceptual term: L1 alone
#   width-16      base width 16 instead of 32
#   width-64      base width 64 (the paper's)
#   crop-256      256x256 crops instead of 128x128 (4x the pixels a step)
#   seed-44       the recipe with seed 44 instead of 43 (crops, augmentation, init): with
#   seed-45       seed-45 and the recipe's own run, the spread one training run can move
# Needs the release binary with the tch feature, as tools/train_default_model.sh says.
# Results: ABLATION_OUT (default ../uwnr-runs/ablation)/<variant>/{run,scores.txt}.
set -euo pipefail
OUT=${ABLATION_OUT:-../uwnr-runs/ablation}
BIN=${BIN:-target/release/uwnr}
declare -A CHANGE=(
  [recipe]='{}'
  [untrained]='{"lr": 1e-12}'
  [no-detail]='{"model": {"detail_retention": false}}'
  [ssim-2]='{"loss": {"perceptual": 2.0}}'
  [l1-only]='{"perceptual_fallback": "none"}'
  [width-16]='{"model": {"base_width": 16}}'
  [width-64]='{"model": {"base_width": 64}}'
  [crop-256]='{"crop": 256}'
  [seed-44]='{"seed": 44}'
  [seed-45]='{"seed": 45}'
)
VARIANTS=("$@")
[ ${#VARIANTS[@]} -gt 0 ] || VARIANTS=(recipe untrained no-detail ssim-2 l1-only width-16 width-64 crop-256 seed-44 seed-45)
for v in "${VARIANTS[@]}"; do
  [ -n "${CHANGE[$v]:-}" ] || { echo "error: unknown variant $v" >&2; exit 2; }
  dir="$OUT/$v"
  mkdir -p "$dir"
  python3 - tools/train_default_model.json "${CHANGE[$v]}" "$dir/config.json" <<'PY'
import json, sys
base = json.load(open(sys.argv[1]))
def merge(a, b):
    for k, v in b.items():
        a[k] = merge(a.get(k, {}), v) if isinstance(v, dict) else v
    return a
json.dump(merge(base, json.loads(sys.argv[2])), open(sys.argv[3], "w"), indent=2)
PY
  if [ ! -f "$dir/scores.txt" ]; then
    extra=()
    [ "$v" = untrained ] && extra=(--max-steps 1)
    start=$(date +%s)
    if [ ${#extra[@]} -gt 0 ]; then
      # One step at learning rate 1e-12: the checkpoint holds the initial weights.
      RUN="$dir/run" CONFIG="$dir/config.json" bash tools/train_default_model.sh "${extra[@]}" > "$dir/train.log" 2>&1
    else
      RUN="$dir/run" CONFIG="$dir/config.json" bash tools/train_default_model.sh > "$dir/train.log" 2>&1
    fi
    secs=$(( $(date +%s) - start ))
    BASELINES=0 WEIGHTS="$dir/run/checkpoints/last/generator.safetensors" \
      bash tools/eval_default_model.sh "$BIN" > "$dir/scores.tmp"
    echo "training wall time: ${secs} s" >> "$dir/scores.tmp"
    mv "$dir/scores.tmp" "$dir/scores.txt"
  fi
  echo "== $v: ${CHANGE[$v]}"
  grep -E '^==|^model|wall' "$dir/scores.txt"
done
