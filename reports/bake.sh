#!/usr/bin/env bash
# Re-measures the figures of reports/bake.md: release build, each bake under /usr/bin/time.
# Usage: reports/bake.sh [SHARED_SCENES_DIR]   (default ../shared/scenes)
set -euo pipefail
cd "$(dirname "$0")/.."
scenes=${1:-../shared/scenes}
cargo build --release -q
bin=$PWD/target/release/cssm
out=$(mktemp -d)
run() { # name, then bake arguments
    local name=$1; shift
    /usr/bin/time -f "$name: %e s wall, %M KB peak" "$bin" bake "$@" -o "$out/$name.cssm" --json 2>"$out/$name.err" >"$out/$name.json" || { cat "$out/$name.err"; return 1; }
    tail -1 "$out/$name.err"
    cat "$out/$name.json"
    "$bin" check "$out/$name.cssm" --json
}
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; commit $(git rev-parse --short HEAD)"
# bake.md's figures are for the Spiral traversal (the default was Spiral then; now Hilbert).
run cornell-64-64 --atlas 64 --cube 64 --traversal spiral
run cornell-64-32 --atlas 64 --cube 32 --traversal spiral
run bunny-128-32 "$scenes/bunny" --atlas 128 --cube 32 --traversal spiral
run sibenik-256-32 "$scenes/sibenik" --atlas 256 --cube 32 --traversal spiral
run cornell-512-64 --atlas 512 --cube 64 --traversal spiral
rm -rf "$out"
