#!/usr/bin/env bash
# Trains the bundled GAN baseline (`--method uwgan`, crates/render/uwnr-gan) with config
# tools/train_uwgan.json: UWGAN's recipe (non-saturating loss, Adam 2e-4, beta1 0.5, one
# generator update per discriminator update) on 128x128 random crops, batch 8, 60 epochs.
# Clean side: every in-air folder and the RGB-D sets of ../shared/data (real depth maps for the
# RGB-D images, the built-in prior for the rest); real underwater side: every reference folder
# (RUIE UCCS and UIQS, U45). No paired data is read.
#
# Run from the repository root. The run folder is ignored by git and survives between sessions;
# run the script again to resume (it passes --resume when the run folder has a config).
# Then: cp "$RUN/checkpoints/last/generator.safetensors" assets/model/uwgan-default.safetensors
set -euo pipefail
DATA=${DATA:-../shared/data}
RUN=${RUN:-runs/uwgan-v1}
DEVICE=${DEVICE:-flex}
BIN=${BIN:-target/release/uwnr}
R="$DATA/references"
ARGS=(gan train
  --clean "$DATA"/inair/* "$DATA"/rgbd/*
  --references "$R"/ruie-uccs/blue "$R"/ruie-uccs/blue-green "$R"/ruie-uccs/green
               "$R"/ruie-uiqs-a "$R"/u45/U45
  --run "$RUN" --device "$DEVICE")
mkdir -p "$(dirname "$RUN")"
if [ -f "$RUN/config.json" ]; then
  exec "$BIN" "${ARGS[@]}" --resume
else
  exec "$BIN" "${ARGS[@]}" --config tools/train_uwgan.json
fi
