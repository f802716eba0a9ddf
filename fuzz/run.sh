#!/bin/sh
# Runs one fuzz target for a fixed time, as the runs in fuzz/README.md were made:
#   fuzz/run.sh TARGET [SECONDS]        (from the repository root; default 180 s)
# One libFuzzer process at a time (-fork=1): a crash, OOM or timeout is saved under
# fuzz/artifacts/TARGET/ and fuzzing goes on. Needs cargo-fuzz and a nightly toolchain.
set -eu
target=$1
seconds=${2:-180}
cd "$(dirname "$0")/.."
dict=""
if [ -f "fuzz/dicts/$target.dict" ]; then
    dict="-dict=fuzz/dicts/$target.dict"
fi
exec cargo +nightly fuzz run "$target" -- \
    -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 \
    -fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
    -print_final_stats=1 $dict
