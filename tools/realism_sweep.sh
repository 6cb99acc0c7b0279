#!/usr/bin/env bash
# A sweep of uwnr's effects on the realism protocol, tuned on one half of the real set and
# confirmed on the other (docs/results/realism-sweep/README.md).
#
#   bash tools/realism_sweep.sh split
#       splits the real set ($REALISM/crops-b/clean, 530 centre crops of half B) by sorted file
#       name into B1 (even indices 0, 2, 4...: tuning) and B2 (odd indices: confirming), as
#       folders of links $OUT/B1 and $OUT/B2; B is the whole real set.
#   SEED=0 SETS="B1" bash tools/realism_sweep.sh NAME=METHOD_JSON[@CAMERA] ... NAME=dir:FOLDER ...
#       renders the 281 in-air photos once after half A with that --method-config (the protocol
#       of tools/realism_levers.sh: -k 1, 256x256, --camera typical unless @CAMERA), into
#       $OUT/renders/NAME-sSEED, or takes an existing folder of renders (dir:FOLDER, e.g. another
#       method's renders of tools/realism_table.sh), and scores it against every real set of
#       $SETS (B1, B2, B). Scores: FID (exact) and KID x1000 (complete U-statistic) by the
#       functions of tools/realism_probe.py / tools/fid_parity.py, on the same FID network.
#       The renders' Inception features are cached ($OUT/features/NAME-sSEED.npy), so scoring
#       the same renders on another real set later costs no second pass.
#   bash tools/realism_sweep.sh table
#       mean ± sample standard deviation over seeds of every (setting, real set) scored so far.
#
# Prints and appends to $OUT/scores.tsv one line per setting and real set:
#   name seed set n_renders n_real FID KIDx1000 strength_mean strength_p10 config
# Environment: OUT (runs/realism-sweep), UWNR_BIN (default target/release/uwnr), PYTHON,
# INCEPTION, REALISM (runs/realism: half-a and crops-b from tools/realism_table.sh), CLEAN
# (../shared/data/inair), SEED (0), SETS ("B1"). Finished renders and features are kept.
# Run it under `nice`: it renders and runs Inception on all cores.
set -euo pipefail
OUT=${OUT:-runs/realism-sweep}
UWNR=${UWNR_BIN:-target/release/uwnr}
PY=${PYTHON:-target/fid-venv/bin/python}
INCEPTION=${INCEPTION:-target/fid/inception-fid-pool3.onnx}
REALISM=${REALISM:-runs/realism}
CLEAN=${CLEAN:-../shared/data/inair}
SEED=${SEED:-0}
SETS=${SETS:-B1}
mkdir -p "$OUT"

if [[ ${1:-} == split ]]; then
    real_abs=$(cd "$REALISM/crops-b/clean" && pwd)
    for h in B1 B2; do rm -rf "${OUT:?}/$h"; mkdir -p "$OUT/$h"; done
    i=0
    while IFS= read -r f; do
        h=$([[ $((i % 2)) -eq 0 ]] && echo B1 || echo B2)
        ln -s "$real_abs/$f" "$OUT/$h/$f"
        i=$((i + 1))
    done < <(cd "$REALISM/crops-b/clean" && ls | LC_ALL=C sort)
    for h in B1 B2; do (cd "$OUT/$h" && ls) >"$OUT/$h.txt"; done
    echo "split: $i real photos, B1 $(wc -l <"$OUT/B1.txt"), B2 $(wc -l <"$OUT/B2.txt")"
    exit 0
fi

if [[ ${1:-} == table ]]; then
    # mean ± sample sd over seeds of each (name, real set) in $OUT/scores.tsv (the last line of
    # a name, seed and set wins): name, set, seeds, FID, KID x1000, strength mean, p10
    awk -F'\t' '
        { key = $1 SUBSEP $3; row = key SUBSEP $2; fid[row] = $6; kid[row] = $7; sm[row] = $8; sp[row] = $9; of[row] = key
          if (!(key in seen)) { seen[key] = 1; order[++n] = key } }
        END {
            for (row in fid) { k = of[row]; c[k]++; f[k] += fid[row]; f2[k] += fid[row]^2; q[k] += kid[row]; q2[k] += kid[row]^2
                               s[k] += sm[row]; p[k] += sp[row]; seeds[k] = seeds[k] " " substr(row, length(k) + 2) }
            for (i = 1; i <= n; i++) { k = order[i]; m = c[k]; split(k, nm, SUBSEP)
                mf = f[k] / m; mq = q[k] / m
                sf = m > 1 ? sqrt((f2[k] - m * mf * mf) / (m - 1)) : 0; sq = m > 1 ? sqrt((q2[k] - m * mq * mq) / (m - 1)) : 0
                printf "%s\t%s\t%d\t%.2f ± %.2f\t%.2f ± %.2f\t%.2f\t%.2f\n", nm[1], nm[2], m, mf, sf, mq, sq, s[k] / m, p[k] / m } }' "$OUT/scores.tsv"
    exit 0
fi

real_dir() {
    case $1 in
        B1 | B2) echo "$OUT/$1" ;;
        B) echo "$REALISM/crops-b/clean" ;;
        *) echo "unknown real set $1" >&2; exit 2 ;;
    esac
}

mkdir -p "$OUT/renders" "$OUT/features" "$OUT/cache"
for item in "$@"; do
    name=${item%%=*}; rest=${item#*=}
    key="$name-s$SEED"
    if [[ $rest == dir:* ]]; then
        dir=${rest#dir:}
        log=$dir.log
        config="renders $dir"
    else
        camera=typical
        if [[ $rest == *@* ]]; then camera=${rest##*@}; rest=${rest%@*}; fi
        dir="$OUT/renders/$key"
        log="$OUT/renders/$key.log"
        config="$rest @$camera"
        if [[ ! -f "$dir/manifest.jsonl" ]]; then
            printf '%s\n' "$rest" >"$OUT/renders/$key.json"
            method=$(printf '%s' "$rest" | sed -n 's/.*"method" *: *"\([a-z]*\)".*/\1/p')
            rm -f "$OUT/features/$key.npy"
            "$UWNR" dataset --clean "$CLEAN" --references "$REALISM/half-a" -k 1 --size 256x256 \
                --seed "$SEED" --method "$method" --method-config "$OUT/renders/$key.json" --camera "$camera" \
                -o "$dir" --no-gallery >"$log" 2>&1 || { echo "$name: uwnr dataset failed, see $log" >&2; continue; }
        fi
    fi
    strength=$(grep -o 'mean [0-9.]* dB, p10 [0-9.]*' "$log" 2>/dev/null | tail -1 | sed 's/mean \([0-9.]*\) dB, p10 \([0-9.]*\)/\1\t\2/')
    [[ -n $strength ]] || strength=$'-\t-'
    reals=()
    for s in $SETS; do reals+=("$s=$(real_dir "$s")"); done
    "$PY" - "$INCEPTION" "$dir/underwater" "$OUT/features/$key.npy" "$OUT/cache" "${reals[@]}" <<'EOF' |
import argparse, hashlib, sys
from pathlib import Path
import numpy as np
sys.path.insert(0, "tools")
from fid_parity import fid_exact, kid_u_statistic, list_images
from realism_probe import features
import onnxruntime as ort

inception, renders, feat_path, cache_dir, *reals = sys.argv[1:]
plain = argparse.Namespace(blur=0.0, noise=0.0, jpeg=0)
session = None
def feats(files, path):
    global session
    if path.exists():
        return np.load(path)
    if session is None:
        session = ort.InferenceSession(inception, providers=["CPUExecutionProvider"])
    f = features(session, files, plain)
    np.save(path, f)
    return f
rf = list_images(Path(renders))
fr = feats(rf, Path(feat_path))
assert len(fr) == len(rf)
for item in reals:
    name, folder = item.split("=", 1)
    files = list_images(Path(folder))
    key = hashlib.sha256("\n".join(str(p) for p in files).encode()).hexdigest()[:16]
    fb = feats(files, Path(cache_dir) / f"real-{name}-{key}.npy")
    print(f"{name}\t{len(fr)}\t{len(fb)}\t{fid_exact(fr, fb):.2f}\t{1000 * kid_u_statistic(fr, fb):.2f}", flush=True)
EOF
    while IFS=$'\t' read -r set n nreal fid kid; do
        line=$(printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s' "$name" "$SEED" "$set" "$n" "$nreal" "$fid" "$kid" "$strength" "$config")
        echo "$line"
        echo "$line" >>"$OUT/scores.tsv"
    done
done
