#!/usr/bin/env bash
# The realism table (issue 49): FID, KID and FD-ct of every method's renders against real
# underwater photos, on the protocol of the paper's Table 2 with our own data.
#
#   UWNR_BIN=target/release/uwnr bash tools/realism_table.sh INCEPTION.onnx [OUT_DIR]
#
# INCEPTION.onnx is the FID network made by tools/export_fid_inception.py (never downloaded
# here). OUT_DIR (default runs/realism) receives everything; docs/RESULTS.md ("Realism") holds
# what one run printed.
#
# Protocol:
# - Every image file under $REFERENCES (default ../shared/data/references, recursively) is listed
#   by its path below that folder, sorted bytewise (LC_ALL=C), and byte-identical copies are
#   dropped (the first path of each content is kept: the same photo filed under two folders would
#   otherwise land in both halves); of the rest, the 1st, 3rd, 5th... form half A (the
#   references), the 2nd, 4th... half B (the real set). The lists are OUT_DIR/half-a.txt and
#   OUT_DIR/half-b.txt, the dropped copies OUT_DIR/copies.txt.
# - Both halves are brought to the renders' form by `uwnr dataset --size 256x256` (scaled to
#   cover, centre-cropped, PNG): the real set and the floor row are the `clean/` side of such a
#   dataset made from the photos of each half.
# - The clean photos ($CLEAN, default ../shared/data/inair, 281) are rendered once each with
#   `uwnr dataset -k 1 --size 256x256 --seed S --references <half A> --method M` for every method
#   and seed; the row "clean photos" is the `clean/` side of those datasets (the same 256x256
#   centre-crops, unrendered).
# - Each set is scored against half B by `uwnr eval --images SET --real HALF_B --seed S`: with
#   `--inception` (FID, KID) and without (FD-ct, uwnr's colour-texture features). KID's subsets
#   are seeded with S. Rows are mean ± sample standard deviation (n - 1) over the seeds. The
#   clean and floor rows do not depend on the render seed: they are scored once, with the first
#   seed (each Inception pass over 800 images takes minutes on 2 cores).
#
# - Every method's renders go through the camera stage of `uwnr dataset` ($CAMERA, default
#   `matched`: lens blur, sensor noise, JPEG; docs/RESULTS.md's earlier tables used `typical`),
#   so that methods meet the real photos on equal terms; the clean side and the real photos are
#   not touched.
#
# Environment: UWNR_BIN (default target/release/uwnr), REFERENCES, CLEAN, SEEDS (default
# "0 1 2"), METHODS (default every method of `uwnr dataset --method` but haze; scored in this
# order, all seeds of one method before the next; an entry NAME=METHOD,ARG,ARG... renders
# METHOD with extra arguments under the row NAME, e.g.
# uwgan-half-a=uwgan,--weights,runs/uwgan-half-a/checkpoints/best/generator.safetensors),
# CAMERA (uwnr dataset --camera), JOBS (uwnr -j).
# Finished steps are kept: running the same command again resumes.
set -euo pipefail

if [[ $# -lt 1 || ! -f "$1" ]]; then
    echo "usage: UWNR_BIN=target/release/uwnr bash tools/realism_table.sh INCEPTION.onnx [OUT_DIR]" >&2
    echo "(make INCEPTION.onnx with tools/export_fid_inception.py)" >&2
    exit 2
fi
MODEL=$1
OUT=${2:-runs/realism}
UWNR=${UWNR_BIN:-target/release/uwnr}
REFERENCES=${REFERENCES:-../shared/data/references}
CLEAN=${CLEAN:-../shared/data/inair}
SEEDS=${SEEDS:-"0 1 2"}
METHODS=${METHODS:-"uwnr uwgan seathru revised uisa reinhard jerlov"}
CAMERA=${CAMERA:-matched}
SIZE=256x256
JOBS_ARG=()
[[ -n "${JOBS:-}" ]] && JOBS_ARG=(-j "$JOBS")

for d in "$REFERENCES" "$CLEAN"; do
    [[ -d "$d" ]] || { echo "missing folder $d" >&2; exit 2; }
done
[[ -x "$UWNR" ]] || { echo "no uwnr binary at $UWNR (set UWNR_BIN)" >&2; exit 2; }
mkdir -p "$OUT"
OUT_ABS=$(cd "$OUT" && pwd)
log() { echo "[$(date +%H:%M:%S)] $*" >&2; }

# 1. The split, and flat folders of links to each half (uwnr eval reads one folder level).
find "$REFERENCES" -type f \( -iname '*.png' -o -iname '*.jpg' -o -iname '*.jpeg' -o -iname '*.bmp' \
    -o -iname '*.tif' -o -iname '*.tiff' -o -iname '*.webp' \) -printf '%P\n' | LC_ALL=C sort >"$OUT/all.txt"
# sha256sum prints "HASH  PATH": the path starts at column 67.
(cd "$REFERENCES" && tr '\n' '\0' <"$OUT_ABS/all.txt" | xargs -0 sha256sum) >"$OUT/sha256.txt"
awk '!seen[$1]++ { print substr($0, 67) }' "$OUT/sha256.txt" >"$OUT/unique.txt"
awk 'seen[$1]++ { print substr($0, 67) }' "$OUT/sha256.txt" >"$OUT/copies.txt"
for half in a b; do
    awk -v r=$([[ $half == a ]] && echo 1 || echo 0) 'NR % 2 == r' "$OUT/unique.txt" >"$OUT/half-$half.txt.new"
    # What an earlier run rendered and scored was made with its own split: refuse to mix.
    if [[ -f "$OUT/half-$half.txt" ]] && ! cmp -s "$OUT/half-$half.txt" "$OUT/half-$half.txt.new"; then
        echo "$OUT/half-$half.txt differs from the split of $REFERENCES: use a new OUT_DIR" >&2
        exit 1
    fi
    mv "$OUT/half-$half.txt.new" "$OUT/half-$half.txt"
done
refs_abs=$(cd "$REFERENCES" && pwd)
for half in a b; do
    rm -rf "$OUT/half-$half"
    mkdir -p "$OUT/half-$half"
    while IFS= read -r rel; do
        ln -s "$refs_abs/$rel" "$OUT/half-$half/${rel//\//__}"
    done <"$OUT/half-$half.txt"
done
log "split: $(wc -l <"$OUT/all.txt") files, $(wc -l <"$OUT/copies.txt") byte-identical copies dropped, $(wc -l <"$OUT/half-a.txt") references (half A), $(wc -l <"$OUT/half-b.txt") real photos (half B)"

dataset() { # OUT_SUBDIR CLEAN_DIR METHOD[,ARG...] SEED
    local spec method extra=()
    IFS=, read -r -a spec <<<"$3"
    method=${spec[0]}
    extra=("${spec[@]:1}")
    "$UWNR" dataset --clean "$2" --references "$OUT/half-a" -k 1 --size "$SIZE" --seed "$4" \
        --method "$method" "${extra[@]}" --camera "$CAMERA" -o "$OUT/$1" --no-gallery "${JOBS_ARG[@]}" >"$OUT/$1.log" 2>&1 ||
        { echo "uwnr dataset failed, see $OUT/$1.log" >&2; exit 1; }
}

# 2. The real set and the floor: each half's photos at the renders' size (the clean/ side).
for half in a b; do
    [[ -d "$OUT/crops-$half/clean" ]] || { log "crops of half ${half^^}"; dataset "crops-$half" "$OUT/half-$half" reinhard 0; }
done
REAL="$OUT/crops-b/clean"

# 3. Renders.
for entry in $METHODS; do
    m=${entry%%=*}
    for s in $SEEDS; do
        [[ -f "$OUT/renders/$m-s$s/manifest.jsonl" && -d "$OUT/renders/$m-s$s/underwater" ]] && continue
        log "render $m seed $s"
        mkdir -p "$OUT/renders"
        dataset "renders/$m-s$s" "$CLEAN" "${entry#*=}" "$s"
    done
done

# 4. Scores.
score() { # NAME IMAGES SEED
    local dir="$OUT/scores/$1-s$3"
    mkdir -p "$dir"
    if [[ ! -f "$dir/fid.json" ]]; then
        log "FID/KID $1 seed $3"
        "$UWNR" eval --images "$2" --real "$REAL" --inception "$MODEL" --seed "$3" --json "$dir/fid.json.tmp" >/dev/null 2>"$dir/fid.log"
        mv "$dir/fid.json.tmp" "$dir/fid.json"
    fi
    if [[ ! -f "$dir/fdct.json" ]]; then
        "$UWNR" eval --images "$2" --real "$REAL" --seed "$3" --json "$dir/fdct.json.tmp" >/dev/null 2>"$dir/fdct.log"
        mv "$dir/fdct.json.tmp" "$dir/fdct.json"
    fi
}
first_seed=${SEEDS%% *}
first_method=${METHODS%% *}
first_method=${first_method%%=*}
score clean "$OUT/renders/$first_method-s$first_seed/clean" "$first_seed"
score floor "$OUT/crops-a/clean" "$first_seed"
for entry in $METHODS; do
    m=${entry%%=*}
    for s in $SEEDS; do
        score "$m" "$OUT/renders/$m-s$s/underwater" "$s"
    done
done

# 5. The table.
row() { # LABEL NAME [SEEDS]
    local label=$1 name=$2
    local files=()
    # A row whose seeds are not all scored yet (an interrupted run) shows those it has.
    for s in ${3:-$SEEDS}; do
        [[ -f "$OUT/scores/$name-s$s/fid.json" && -f "$OUT/scores/$name-s$s/fdct.json" ]] && files+=("$OUT/scores/$name-s$s")
    done
    if [[ ${#files[@]} -eq 0 ]]; then
        echo "| $label | not scored | | |"
        return
    fi
    [[ ${#files[@]} -lt $(wc -w <<<"${3:-$SEEDS}") ]] && label="$label (seeds $(for f in "${files[@]}"; do echo -n "${f##*-s} "; done | sed 's/ $//'))"
    # Per quantity "mean std" (std empty for one seed), then fixed decimals.
    local stats
    stats=$(jq -rn '
        def stats: (add / length) as $m
            | "\($m) \(if length > 1 then ((map((. - $m) * (. - $m)) | add) / (length - 1)) | sqrt else "-" end)";
        [inputs] as $all
        | [($all | map(select(.kind == "fid") | .sets.fid) | stats),
           ($all | map(select(.kind == "fid") | .sets.kid * 1000) | stats),
           ($all | map(select(.kind == "fdct") | .sets.fd_ct) | stats)] | join(" ")' \
        < <(for f in "${files[@]}"; do jq -c '. + {kind: "fid"}' "$f/fid.json"; jq -c '. + {kind: "fdct"}' "$f/fdct.json"; done))
    awk -v title="$label" '{
        cell = "";
        for (i = 1; i <= 6; i += 2) {
            d = (i == 5) ? 2 : 1;
            v = sprintf("%." d "f", $i);
            if ($(i + 1) != "-") v = v sprintf(" ± %." d "f", $(i + 1));
            cell = cell " | " v;
        }
        print "| " title cell " |";
    }' <<<"$stats"
}
n_clean=$(find "$OUT/renders/$first_method-s$first_seed/underwater" -type f | wc -l)
n_real=$(find "$REAL" -type f | wc -l)
{
    echo "| renders | FID | KID x1000 | FD-ct |"
    echo "|---|---:|---:|---:|"
    row "the clean photos themselves" clean "$first_seed"
    for entry in $METHODS; do row "${entry%%=*}" "${entry%%=*}"; done
    row "real photos of half A (the floor)" floor "$first_seed"
    echo
    echo "$n_clean renders per method and seed against $n_real real photos (half B), every method's through the camera stage \`$CAMERA\`; methods: mean ± std over seeds $SEEDS; clean and floor: seed $first_seed"
} >"$OUT/table.md"
cat "$OUT/table.md"
