#!/usr/bin/env bash
# GPU figures of reports/runtime.md, for the device machine (../shared/design/gpu-machine.md).
# Here: build, then carry .gl and .carry. There: run this script from the repository root.
#
#   Here:   reports/runtime.sh prepare
#   Device: reports/runtime.sh measure      (writes $OUT/runtime-*.txt and CSV)
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in
prepare)
    cargo build --release
    cargo bench --bench gpu_queries --no-run 2>&1 | tail -1
    bench=$(ls -t target/release/deps/gpu_queries-* | grep -v '\.d$' | head -1)
    (cd ../shared/tools/gpu-limit && cargo build --release)
    mkdir -p .carry/scenes
    cp target/release/cssm "$bench" ../shared/tools/gpu-limit/target/release/gpu-limit .carry/
    mv ".carry/$(basename "$bench")" .carry/gpu_queries
    cp -r ../shared/scenes/sibenik .carry/scenes/ 2>/dev/null || echo "no sibenik: its rows will be skipped"
    du -sh .carry
    ;;
measure)
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    out=${OUT:-/tmp/out}
    mkdir -p "$out"
    nvidia-smi -L > "$out/runtime-device.txt" 2>&1 || true
    .carry/gpu-limit --sizes-mb 8,512 --r 64,256 --qlog2 26 --reps 20 | tee "$out/runtime-gpu-limit.txt"
    .carry/gpu_queries --scenes .carry/scenes --atlas 128 --cube 32 --csv "$out/runtime-queries.csv" \
        | tee "$out/runtime-queries.txt"
    for size in 640x480 1280x720; do
        .carry/cssm render --size "$size" --timings --out "$out/direct-$size.png" \
            | tee "$out/runtime-direct-$size.txt"
    done
    ;;
*)
    echo "usage: $0 prepare|measure" >&2
    exit 2
    ;;
esac
