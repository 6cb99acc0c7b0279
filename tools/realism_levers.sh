#!/usr/bin/env bash
# One realism figure per setting of the uwnr method or the camera (issue 49, "every lever
# measured alone"): for each NAME=METHOD_JSON[@CAMERA], renders the 281 in-air photos once after
# half A (the protocol of tools/realism_table.sh, seed 0, 256x256) with that --method-config and
# --camera (default typical), and scores the renders against half B with tools/realism_probe.py
# (uwnr's FID; KID as the complete U-statistic, i.e. without uwnr eval's subset noise).
#
#   bash tools/realism_levers.sh OUT_DIR 'none={"method":"uwnr","effects":{}}' \
#       'particles={"method":"uwnr","effects":{"particles":40}}' ...
#
# Needs runs/realism from tools/realism_table.sh (the split and half B's crops) and the FID
# network at $INCEPTION (default target/fid/inception-fid-pool3.onnx). Prints one line per
# setting: name, FID, KID x1000, strength mean and 10th percentile. Finished settings are kept.
set -euo pipefail
OUT=$1; shift
UWNR=${UWNR_BIN:-target/release/uwnr}
PY=${PYTHON:-target/fid-venv/bin/python}
INCEPTION=${INCEPTION:-target/fid/inception-fid-pool3.onnx}
REALISM=${REALISM:-runs/realism}
CLEAN=${CLEAN:-../shared/data/inair}
SEED=${SEED:-0}
mkdir -p "$OUT"
for item in "$@"; do
    name=${item%%=*}; rest=${item#*=}
    camera=typical
    if [[ $rest == *@* ]]; then camera=${rest##*@}; rest=${rest%@*}; fi
    dir="$OUT/$name"
    if [[ ! -f "$dir/manifest.jsonl" ]]; then
        printf '%s\n' "$rest" >"$OUT/$name.json"
        method=$(printf '%s' "$rest" | sed -n 's/.*"method" *: *"\([a-z]*\)".*/\1/p')
        "$UWNR" dataset --clean "$CLEAN" --references "$REALISM/half-a" -k 1 --size 256x256 \
            --seed "$SEED" --method "$method" --method-config "$OUT/$name.json" --camera "$camera" \
            -o "$dir" --no-gallery >"$OUT/$name.log" 2>&1 || { echo "$name: uwnr dataset failed, see $OUT/$name.log" >&2; continue; }
    fi
    if [[ ! -f "$OUT/$name.score" ]]; then
        "$PY" tools/realism_probe.py --inception "$INCEPTION" --real "$REALISM/crops-b/clean" "$dir/underwater" >"$OUT/$name.score"
    fi
    strength=$(grep -o 'mean [0-9.]* dB, p10 [0-9.]*' "$OUT/$name.log" | tail -1)
    printf '%s\t%s\t%s\n' "$name" "$(cut -f3,4 "$OUT/$name.score")" "$strength"
done
