#!/usr/bin/env bash
# The full downstream experiment behind docs/RESULTS.md: one synthetic training set per method
# from the clean images of ../shared/data (inair + the rgb folders of rgbd; depth: the rgbd
# sets' measured maps beside them, the built-in prior elsewhere, as `uwnr dataset` reads depth:
# trusted fully, a scene scale drawn per pair; runs before the depth policy used the prior
# everywhere at the render trust) with the references of
# ../shared/data/references (4 per clean image, 256x256), Shallow-UWnet trained on each and on
# the real euvp-dark pairs with the same budget (6,000 samples: 1,500 steps of 4 x 128²),
# scored on uieb-val, lsui and lsui-test (the 27 LSUI pairs held out from the bundled model's
# training by tools/lsui_split.sh, made in SPLITS). The bundled model renders the uwnr set.
#
# Run from the repository root; run it again to continue after a stop (every stage resumes).
# Needs the release binary with the tch feature (about 2.5-3 hours on a 2-core CPU), built against
# pip's torch in the python3 on PATH: tch 0.22 expects torch 2.9.0 (`pip install torch==2.9.0`;
# with another 2.9.x add LIBTORCH_BYPASS_VERSION_CHECK=1):
#   LIBTORCH_USE_PYTORCH=1 cargo build --release -p uwnr-cli --features tch
set -euo pipefail
DATA=${DATA:-../shared/data}
OUT=${OUT:-../uwnr-runs/downstream-v1}
DEVICE=${DEVICE:-tch}
BIN=${BIN:-target/release/uwnr}
# METHODS and REAL choose the rows: e.g. METHODS=uwgan REAL= adds one method's row to an earlier
# run's table (the same seed, budget and tests give the same conditions); unset, the rows are
# `uwnr experiment downstream`'s default methods.
METHODS=${METHODS-}
# SEED draws the references and seeds every training (docs/RESULTS.md repeats some rows with
# SEED=1 and SEED=2, each in its own OUT).
SEED=${SEED:-0}
REAL=${REAL-$DATA/paired/euvp-dark}
# TARGET calibrates the bundled model's set to a water (`uwnr dataset --target`): e.g.
# TARGET=$DATA/paired/uieb-train or TARGET=../uwnr-splits/lsui-train; the baselines' sets ignore it.
TARGET=${TARGET-}
# WEIGHTS renders the uwnr set with another UWNR model than the bundled one (e.g. the v4 rows of
# docs/RESULTS.md: WEIGHTS=FILE with v4's file from the commit that bundled it).
WEIGHTS=${WEIGHTS-}
# METHOD_CONFIG renders the uwnr set with a method spec (`--method-config`), e.g. another model's
# effects with an earlier build (docs/results/model-v7-downstream.md).
METHOD_CONFIG=${METHOD_CONFIG-}
# CAMERA sets the camera stage of every training set (`--camera`: none, matched, typical or JSON);
# unset, `uwnr experiment downstream`'s default (matched).
CAMERA=${CAMERA-}
SPLITS=${SPLITS:-../uwnr-splits}
[ -d "$SPLITS/lsui-test" ] || bash tools/lsui_split.sh "$SPLITS" >/dev/null
export LIBTORCH_USE_PYTORCH=1
if [ "$DEVICE" = tch ] && [ -z "${LIBTORCH:-}" ]; then
  TORCH_LIB=$(python3 -c 'import os, torch; print(os.path.join(os.path.dirname(torch.__file__), "lib"))')
  export LD_LIBRARY_PATH="$TORCH_LIB:${LD_LIBRARY_PATH:-}"
fi
mkdir -p "$(dirname "$OUT")"
exec "$BIN" experiment downstream \
  --clean "$DATA/inair" "$DATA"/rgbd/*/rgb \
  --references "$DATA/references" \
  --test "$DATA/paired/uieb-val" "$DATA/paired/lsui" "$SPLITS/lsui-test" \
  ${REAL:+--real "$REAL"} ${TARGET:+--target "$TARGET"} \
  ${WEIGHTS:+--weights "$WEIGHTS"} ${METHOD_CONFIG:+--method-config "$METHOD_CONFIG"} ${CAMERA:+--camera "$CAMERA"} \
  ${METHODS:+--methods "$METHODS"} --per-image 4 --size 256x256 \
  --budget 6000 --seed "$SEED" --device "$DEVICE" --out "$OUT"
