#!/usr/bin/env bash
# Re-measures the figures of reports/visibility.md: bakes at the issue's settings, each checked
# with `cssm check` (100,000 pairs, seed 1) asking both ends (the default) and one end (--one-end).
# Usage: reports/visibility.sh [SHARED_SCENES_DIR] [--sibenik]   (default ../shared/scenes; the
# full Sibenik at atlas 512, cube 64 takes long on few cores and runs only with --sibenik)
set -euo pipefail
cd "$(dirname "$0")/.."
scenes=${1:-../shared/scenes}
cargo build --release -q --bin cssm
bin=$PWD/target/release/cssm
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# The compression report's 3,700-face church, from "$scenes/sibenik".
"$bin" report church --scenes "$scenes" --out "$out/church" >/dev/null
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; commit $(git rev-parse --short HEAD)"
measure() { # name, then bake arguments
    local name=$1; shift
    "$bin" bake "$@" -o "$out/$name.cssm" --json >"$out/$name.json" 2>>"$out/warnings"
    local runs gpu
    runs=$(grep -o '"runs":[0-9]*' "$out/$name.json" | cut -d: -f2)
    gpu=$(grep -o '"gpu_bytes":[0-9]*' "$out/$name.json" | cut -d: -f2)
    for q in both one; do
        local flag=""; [ $q = one ] && flag=--one-end
        echo "$name $q-end runs=$runs gpu_bytes=$gpu $("$bin" check "$out/$name.cssm" $flag --json 2>>"$out/warnings")"
    done
}
# The scene's diameter: the far plane of a small bake.
diameter() {
    "$bin" bake "$1" --atlas 128 --cube 8 -o "$out/d.cssm" --json >/dev/null 2>>"$out/warnings"
    "$bin" inspect "$out/d.cssm" --json | grep -o '"far":[0-9.e+-]*' | cut -d: -f2
}
measure cornell-64-32 --atlas 64 --cube 32
for f in 0.002 0.001 0.0005 0.00025; do
    near=$(python3 -c "print($f * $(diameter "$out/church"))")
    measure "church-256-32-near$f" "$out/church" --atlas 256 --cube 32 --near "$near"
done
if [ "${2:-}" = --sibenik ]; then
    measure sibenik-512-64 reports/scenes/sibenik --atlas 512 --cube 64
fi
