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
    cargo bench --bench frame_time --no-run 2>&1 | tail -1
    cargo bench --bench rsm_time --no-run 2>&1 | tail -1
    cargo bench --bench vct_time --no-run 2>&1 | tail -1
    cargo bench --bench ssil_time --no-run 2>&1 | tail -1
    cargo bench --bench vf_time --no-run 2>&1 | tail -1
    bench=$(ls -t target/release/deps/gpu_queries-* | grep -v '\.d$' | head -1)
    frame_bench=$(ls -t target/release/deps/frame_time-* | grep -v '\.d$' | head -1)
    rsm_bench=$(ls -t target/release/deps/rsm_time-* | grep -v '\.d$' | head -1)
    vct_bench=$(ls -t target/release/deps/vct_time-* | grep -v '\.d$' | head -1)
    ssil_bench=$(ls -t target/release/deps/ssil_time-* | grep -v '\.d$' | head -1)
    vf_bench=$(ls -t target/release/deps/vf_time-* | grep -v '\.d$' | head -1)
    (cd ../shared/tools/gpu-limit && cargo build --release)
    mkdir -p .carry/scenes
    cp target/release/cssm "$bench" ../shared/tools/gpu-limit/target/release/gpu-limit .carry/
    mv ".carry/$(basename "$bench")" .carry/gpu_queries
    cp "$frame_bench" .carry/frame_time
    cp "$rsm_bench" .carry/rsm_time
    cp "$vct_bench" .carry/vct_time
    cp "$ssil_bench" .carry/ssil_time
    cp "$vf_bench" .carry/vf_time
    mkdir -p .carry/scenes/sibenik-view && cp reports/scenes/sibenik/scene.toml .carry/scenes/sibenik-view/
    sed -i 's|mesh = .*|mesh = "../sibenik/sibenik.obj"|' .carry/scenes/sibenik-view/scene.toml
    cp -r ../shared/scenes/sibenik .carry/scenes/ 2>/dev/null || echo "no sibenik: its rows will be skipped"
    # GI scenes (Table 1: 128x128 texels): the Cornell box and the heads baked here; the church
    # is baked on the device (16 cores), its atlas needing 256.
    target/release/cssm bake -o .carry/cornell.cssm --atlas 128 --cube 32
    if target/release/cssm report heads --scenes ../shared/scenes --out .carry/scenes/heads; then
        target/release/cssm bake .carry/scenes/heads -o .carry/heads.cssm --atlas 128 --cube 32
    fi
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
    # The persistent renderer's frame against a one-shot render (issue 16), with GPU ms per pass.
    .carry/frame_time --size 640x480 --frames 20 --one-shots 5 --out "$out/runtime-frame-time.md" \
        | tee "$out/runtime-frame-time.txt"
    for size in 640x480 1280x720; do
        .carry/cssm render --size "$size" --timings --out "$out/direct-$size.png" \
            | tee "$out/runtime-direct-$size.txt"
    done
    # RSM with and without the micro linear buffer (issue 17; target: 1 ms at 1280x720 with
    # visibility), static and moving light, GPU ms per pass.
    .carry/rsm_time --size 1280x720 --frames 20 --out "$out/runtime-rsm-cornell.md" \
        | tee "$out/runtime-rsm-cornell.txt"
    if [ -d .carry/scenes/sibenik ]; then
        .carry/rsm_time --scene .carry/scenes/sibenik-view --size 1280x720 --frames 20 \
            --out "$out/runtime-rsm-sibenik.md" | tee "$out/runtime-rsm-sibenik.txt"
    fi
    # VCT per voxel resolution (issue 18; target: 2 ms at 1280x720 on the Cornell box), static
    # and moving light, GPU ms per pass, and the pools' memory against a dense grid.
    .carry/vct_time --size 1280x720 --frames 20 --resolutions 64,128,256 \
        --out "$out/runtime-vct-cornell.md" | tee "$out/runtime-vct-cornell.txt"
    if [ -d .carry/scenes/sibenik ]; then
        .carry/vct_time --scene .carry/scenes/sibenik-view --size 1280x720 --frames 20 \
            --resolutions 128,256,512 --out "$out/runtime-vct-sibenik.md" \
            | tee "$out/runtime-vct-sibenik.txt"
    fi
    # SSIL at Fig. 9's settings with and without visibility (issue 19; targets at 1280x720:
    # 0.5 ms without, 1.5 ms with visibility), GPU ms per pass.
    .carry/ssil_time --size 1280x720 --frames 20 --out "$out/runtime-ssil-cornell.md" \
        | tee "$out/runtime-ssil-cornell.txt"
    if [ -d .carry/scenes/sibenik ]; then
        .carry/ssil_time --scene .carry/scenes/sibenik-view --size 1280x720 --frames 20 \
            --out "$out/runtime-ssil-sibenik.md" | tee "$out/runtime-ssil-sibenik.txt"
    fi
    # VF at Table 1's marching sizes with and without the filter (issue 20; target: 2 ms at
    # 1280x720 on the Cornell box), GPU ms per pass.
    .carry/vf_time --size 1280x720 --frames 20 --out "$out/runtime-vf-cornell.md" \
        | tee "$out/runtime-vf-cornell.txt"
    if [ -d .carry/scenes/sibenik ]; then
        .carry/vf_time --scene .carry/scenes/sibenik-view --size 1280x720 --frames 20 \
            --out "$out/runtime-vf-sibenik.md" | tee "$out/runtime-vf-sibenik.txt"
    fi
    # Every method side by side (issue 27): `cssm compare` on the built-in boxes at 640x480,
    # GPU ms per pass and memory on the real GPU, the references path traced on the device's
    # cores; the page stays in /tmp, its figures come back.
    .carry/cssm compare --size 640x480 --samples 512 --out /tmp/compare \
        > "$out/runtime-compare.txt" 2>&1 || true
    cp /tmp/compare/compare.md /tmp/compare/compare.csv /tmp/compare/compare.json \
        /tmp/compare/chart.svg "$out/" 2>/dev/null || echo "compare wrote no page"
    # Global illumination, GPU ms per pass (Table 1): final gather (lightcuts) and the atlas
    # lightmap, 1 and 2 bounces, 640x480.
    if [ -d .carry/scenes/sibenik ]; then
        .carry/cssm bake .carry/scenes/sibenik -o /tmp/church.cssm --atlas 256 --cube 32 \
            | tail -3 | tee "$out/runtime-church-bake.txt"
    fi
    for scene in cornell heads church; do
        case $scene in
        cornell) dir="" cssm=.carry/cornell.cssm ;;
        heads) dir=.carry/scenes/heads cssm=.carry/heads.cssm ;;
        church) dir=.carry/scenes/sibenik cssm=/tmp/church.cssm ;;
        esac
        [ -f "$cssm" ] || { echo "no $scene: its GI rows are skipped"; continue; }
        for method in lightcuts lightmap; do
            for bounces in 1 2; do
                name=gi-$scene-$method-$bounces
                .carry/cssm render $dir --cssm "$cssm" --method $method --bounces $bounces \
                    --size 640x480 --timings --out "$out/$name.png" | tee "$out/runtime-$name.txt"
            done
        done
    done
    ;;
*)
    echo "usage: $0 prepare|measure" >&2
    exit 2
    ;;
esac
