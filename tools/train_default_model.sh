#!/usr/bin/env bash
# Trains the bundled default model (v4, the `anchored` variant with detail retention:
# crates/render/uwnr-model/src/style/mod.rs) with config tools/train_default_model.json (CONFIG= another):
# base width 32, inputs clean + absolute light field + the anchor (Reinhard lαβ transfer with
# the reference's light field and share of detail retained), output a smooth gain and offset on the anchor, then the
# depth-driven image-formation stage (depth is not fed to the network). Loss: L1 + 0.5 (1 - SSIM).
# Data: the training part of paired/lsui only (tools/lsui_split.sh; the 27 pairs of
# assets/splits/lsui-test.txt are never seen), listed 8 times so an epoch has 648 samples;
# validated on paired/uieb-val. (With paired/euvp-dark in the mix, validation fell 2.2 dB below
# the untrained start in the first epoch: what the correction learns there does not transfer.)
# Baselines on uieb-val: mean shift 20.96 dB, Reinhard lαβ 29.44 dB.
# (v2, the paper's generator: tools/train_model_v2.json, in the git history of this script.)
#
# Run from the repository root. The run folder lives outside the repository so it survives;
# run the script again to resume (it passes --resume when the run folder has a checkpoint).
# Needs the release binary with the tch feature (pip torch 2.9.x in the python3 on PATH):
#   LIBTORCH_USE_PYTORCH=1 LIBTORCH_BYPASS_VERSION_CHECK=1 cargo build --release -p uwnr-cli --features tch
set -euo pipefail
DATA=${DATA:-../shared/data}
SPLITS=${SPLITS:-../uwnr-splits}
RUN=${RUN:-../uwnr-runs/default-v4}
DEVICE=${DEVICE:-tch}
BIN=${BIN:-target/release/uwnr}
export LIBTORCH_USE_PYTORCH=1
if [ -z "${LIBTORCH:-}" ]; then
  TORCH_LIB=$(python3 -c 'import os, torch; print(os.path.join(os.path.dirname(torch.__file__), "lib"))')
  export LD_LIBRARY_PATH="$TORCH_LIB:${LD_LIBRARY_PATH:-}"
fi
[ -d "$SPLITS/lsui-train" ] || bash tools/lsui_split.sh "$SPLITS"
mkdir -p "$(dirname "$RUN")"
CONFIG=${CONFIG:-tools/train_default_model.json}
L="$SPLITS/lsui-train"
ARGS=(train
  --data "$L" "$L" "$L" "$L" "$L" "$L" "$L" "$L"
  --val "$DATA/paired/uieb-val"
  --run "$RUN" --device "$DEVICE" --val-refs 20.96,29.44)
# Extra arguments go to `uwnr train` (e.g. --max-steps N).
if [ -f "$RUN/config.json" ]; then
  exec "$BIN" "${ARGS[@]}" --resume "$@"
else
  exec "$BIN" "${ARGS[@]}" --config "$CONFIG" "$@"
fi
