#!/usr/bin/env bash
# Makes the bundled default model v5 and its water bank (MODEL_CARD.md says why it ships so):
# 1. `uwnr water fit` on the real pairs of paired/uieb-train and the training part of paired/lsui
#    (tools/lsui_split.sh) writes assets/model/water-bank.json (the regression that reads a
#    reference's water off its statistics), scored on the held-out uieb-val and lsui-test;
# 2. the anchored network with the water anchor (tools/train_model_v5.json) at its initial weights
#    (one step at learning rate 1e-12, so the correction stays at zero: training it with the v4
#    recipe lowered self-reconstruction by 1.5 dB on uieb-val and 2.2 dB on lsui-test);
# 3. `uwnr convert` to float16 with the provenance in the metadata.
# The bank is embedded at build time: rebuild after step 1 before step 2 uses it.
# Run from the repository root: bash tools/make_default_model_v5.sh [BIN]
set -euo pipefail
BIN=${1:-${BIN:-target/release/uwnr}}
DATA=${DATA:-../shared/data}
SPLITS=${SPLITS:-../uwnr-splits}
RUN=${RUN:-../uwnr-runs/default-v5-untrained}
[ -d "$SPLITS/lsui-train" ] || bash tools/lsui_split.sh "$SPLITS" >/dev/null
"$BIN" water fit "$DATA/paired/uieb-train" "$SPLITS/lsui-train" \
  --check "$DATA/paired/uieb-val" "$SPLITS/lsui-test" -o assets/model/water-bank.json
CONFIG=$(mktemp)
trap 'rm -f "$CONFIG"' EXIT
python3 -c 'import json,sys; c=json.load(open("tools/train_model_v5.json")); c["lr"]=1e-12; json.dump(c,open(sys.argv[1],"w"))' "$CONFIG"
rm -rf "$RUN"
"$BIN" train --data "$SPLITS/lsui-train" --val "$DATA/paired/uieb-val" --run "$RUN" \
  --device flex --config "$CONFIG" --max-steps 1
"$BIN" convert "$RUN/checkpoints/last/generator.safetensors" assets/model/uwnr-default.safetensors \
  --dtype f16 --source "uwnr default model v5 (anchored variant, water anchor, detail retention above a noise floor, correction at zero, base width 32): tools/make_default_model_v5.sh; see MODEL_CARD.md"
