#!/usr/bin/env bash
# Regenerates reports/compression.md, compression.csv and compression.svg: the paper's Tables 2
# and 3 (Cornell box, Cornell Heads, Sibenik as the church, in full and at 3,700 faces) and one
# row per option beyond the paper, every figure measured by `cssm report compression` (release build).
#
# Usage: reports/compression.sh [SHARED_SCENES_DIR] [more flags for `cssm report compression`]
#   SHARED_SCENES_DIR defaults to ../shared/scenes (teapot/, bunny/, sibenik/).
#   e.g. reports/compression.sh ../shared/scenes --scene cornell   # the Cornell box's rows only
#
# Run it on a quiet machine: rows are timed. On a 2-core AMD EPYC (2026-12-05) the whole grid took
# 30 minutes: the Cornell box's rows 2, the heads 8, the church 14, the church at 3,700 faces 5 (see
# the report's "Time per table"; on this shared machine the same rows' times vary by 10-20% from run
# to run). On a 2-core Intel Xeon, before the rasteriser and the faster compressor, it took 59.
set -euo pipefail
cd "$(dirname "$0")/.."
scenes=${1:-../shared/scenes}
shift || true
cargo build --release -q
bin=${CARGO_TARGET_DIR:-$PWD/target}/release/cssm
if ! git diff --quiet HEAD -- . ':(exclude)reports'; then
    echo "warning: uncommitted changes; the report will name the commit as -dirty" >&2
fi
"$bin" report compression --scenes "$scenes" --out reports "$@"
