#!/usr/bin/env bash
# Build times from scratch (an empty target folder each, release profile, the dependencies
# already downloaded) of what a user builds first:
#   python    `cargo build --release -p uwnr-python` (what `pip install ./python` compiles)
#   default   `cargo build --release -p uwnr-cli` (what `cargo install --path crates/uwnr-cli` compiles)
#   render    the render-only binary: `-p uwnr-cli --no-default-features --features bundled-model,onnx`
#   lean      the same without ONNX models: `--features bundled-model`
# Run on a quiet machine from a checkout's root: `bash tools/build_times.sh [python default render lean]`.
# Prints wall and CPU seconds (user + system) per build and the number of crates compiled.
set -euo pipefail
builds=("$@")
[ $# -eq 0 ] && builds=(python default render lean)
for b in "${builds[@]}"; do
  case $b in
    python) args=(-p uwnr-python) ;;
    default) args=(-p uwnr-cli) ;;
    render) args=(-p uwnr-cli --no-default-features --features bundled-model,onnx) ;;
    lean) args=(-p uwnr-cli --no-default-features --features bundled-model) ;;
    *) echo "unknown build $b" >&2; exit 2 ;;
  esac
  dir=$(mktemp -d)
  start=$(date +%s.%N)
  /usr/bin/time -f "%U %S" -o "$dir/cpu" cargo build --release --locked --quiet "${args[@]}" \
    --target-dir "$dir/target"
  end=$(date +%s.%N)
  read -r user sys < "$dir/cpu"
  crates=$(find "$dir/target/release/.fingerprint" -mindepth 1 -maxdepth 1 -type d | wc -l)
  printf '%-8s wall %6.0f s   cpu %6.0f s   %d units compiled\n' "$b" \
    "$(echo "$end - $start" | bc)" "$(echo "$user + $sys" | bc)" "$crates"
  rm -rf "$dir"
done
