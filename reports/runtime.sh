#!/usr/bin/env bash
# GPU figures of reports/runtime.md, for the device machine (../shared/design/gpu-machine.md).
# Here: build, then carry .gl and .carry. There: run this script from the repository root.
#
#   Here:   reports/runtime.sh prepare
#   Device: reports/runtime.sh measure      (writes $OUT/runtime.tar.gz: runtime-*.txt, *.md,
#                                            CSV and images, packed again after every step, since
#                                            the device tool returns at most 8 files)
#
#   Anywhere: reports/runtime.sh smoke      (the whole harness at small sizes on this machine's
#                                            device, lavapipe included, into a temporary carry
#                                            folder; fails if any step fails: scripts/test.sh
#                                            runs it so that no device time goes to a broken
#                                            script)
#
# `prepare --small` and `measure --small` are the two halves of `smoke`. CSSM_CARRY names the
# carry folder (default .carry). Every step of `measure` runs even when one before it failed
# (the device's time is short: whatever worked comes back); the failed ones are listed in
# runtime-failures.txt and the script exits non-zero). MEASURE_BUDGET (seconds, default none)
# skips the steps that would start after it and cuts the one running at it; STEP_LIMIT (seconds)
# cuts any single step; both so that one device call returns whatever fitted. The steps run in
# order of what the reports lack most. The first renders one small image and stops everything
# when no GPU answers (or, where nvidia-smi exists, when the adapter is not NVIDIA's).
#
# What travels must stay under 64 MiB: `prepare` strips the executables and packs them with the
# scenes into $carry/pack.tar.xz (xz, or Python's lzma where the device lacks xz).
set -euo pipefail
cd "$(dirname "$0")/.."

carry=${CSSM_CARRY:-.carry}
small=0
[ "${2:-}" = "--small" ] && small=1
benches="gpu_queries moving_queries frame_time method_time vct_pools"
gpu_limit=../shared/tools/gpu-limit
shared_scenes=../shared/scenes

if [ $small = 1 ]; then
    # Small enough for lavapipe on two cores; the same steps and options as the full run.
    bake_cornell="--atlas 32 --cube 8"
    bake_table1="--atlas 128 --cube 8"
    bake_sibenik="--atlas 256 --cube 8"
    queries="--atlas 128 --cube 8 --pairs 4096 --receivers 1024 --senders 16 --reps 2 --tile-sizes 32x24,64x48 --tile-senders 8"
    moving="--atlas 32 --cube 8 --pairs 4096 --objects 1 --reps 2"
    bake_bunny="--atlas 32 --cube 8"
    gpu_bakes="cornell-64:--atlas=32,--cube=8"
    gpu_bakes_scenes="teapot:--atlas=32,--cube=8"
    xz_level=1
    limit_args="--small"
    frames=2
    one_shots=1
    # Every method's persistent frame without its one-shots: each one-shot builds a renderer
    # whose prepare passes (the converging bounces) take most of the smoke's time on lavapipe;
    # the frame-time step still runs the one-shot path.
    one_shots_all=0
    frame_size=32x24
    # The frame-time steps' own bake of the Cornell box (the full run: the bench's atlas 64,
    # cube 32), and vct's voxel grid in the every-method row: at its default resolution its
    # prepare alone takes minutes on lavapipe.
    frame_bake="--atlas 32 --cube 8"
    all_overrides="--method vct:resolution=16"
    links_bake="--atlas 32 --cube 8"
    view_sizes="32x24 48x32"
    wide=32x24
    shadow="--shadow-resolution 256"
    # --sweep per method and scene (bash names: sweep_METHOD_SCENE), the rows' one varied
    # option; a method without one runs its rows as its table entry names them.
    sweep_vct_cornell="resolution=16,32"
    sweep_vct_sibenik="resolution=32"
    compare="--size 32x24 --samples 2 --atlas 32 --cube 8 --shadow-resolution 256"
    gi_size=32x24
else
    bake_cornell="--atlas 128 --cube 32"
    bake_table1="--atlas 128 --cube 32"
    bake_sibenik="--atlas 256 --cube 32"
    queries="--atlas 128 --cube 32 --tile-sizes 320x240,640x480,1280x720"
    moving="--atlas 64 --cube 32"
    bake_bunny="--atlas 128 --cube 32"
    # The bake on the GPU (issue 25): Table 3's two Cornell rows (targets: 1 s at atlas 64 on
    # two cores, 5 s at atlas 512 on the H200), the teapot, the bunny and the full Sibenik.
    gpu_bakes="cornell-64:--atlas=64,--cube=64 cornell-512:--atlas=512,--cube=64"
    gpu_bakes_scenes="teapot:--atlas=256,--cube=64 bunny:--atlas=256,--cube=64"
    gpu_bakes_scenes+=" sibenik:--atlas=512,--cube=64"
    xz_level=9
    limit_args="--sizes-mb 8,512 --r 64,256 --qlog2 26 --reps 20"
    frames=20
    one_shots=5
    one_shots_all=1
    frame_size=640x480
    frame_bake=""
    all_overrides=""
    # Table 1's bake (the links at atlas 128: 267 MB, reports/final-gather.md).
    links_bake="--atlas 128 --cube 32"
    view_sizes="640x480 1280x720"
    wide=1280x720
    shadow=""
    sweep_vct_cornell="resolution=64,128,256"
    sweep_vct_sibenik="resolution=128,256,512"
    # GPU ms per pass of every method at 640x480; the error figures of reports/compare.md come
    # from 1024 paths per pixel, these references only need to exist.
    compare="--size 640x480 --samples 64"
    gi_size=640x480
fi

prepare() {
    cargo build --release
    mkdir -p "$carry/scenes"
    cp target/release/cssm "$carry/"
    for bench in $benches; do
        # cargo names the executable it built: "Executable benches/NAME.rs (target/...)".
        exe=$(cargo bench --bench "$bench" --no-run 2>&1 | sed -n 's/.*Executable .*(\(.*\)).*/\1/p')
        [ -x "$exe" ] || { echo "cargo built no executable for the $bench bench" >&2; exit 1; }
        cp "$exe" "$carry/$bench"
    done
    if [ $small = 0 ]; then
        (cd "$gpu_limit" && cargo build --release)
    fi
    if [ -x "$gpu_limit/target/release/gpu-limit" ]; then
        cp "$gpu_limit/target/release/gpu-limit" "$carry/"
    else
        echo "no $gpu_limit/target/release/gpu-limit: the ceiling is not measured" >&2
    fi
    for scene in sibenik bunny teapot; do
        if [ -d "$shared_scenes/$scene" ]; then
            cp -r "$shared_scenes/$scene" "$carry/scenes/"
        else
            echo "no $shared_scenes/$scene: its rows will be skipped" >&2
        fi
    done
    if [ -d "$carry/scenes/bunny" ]; then
        # The Cornell box with the bunny as a moving object (issue 21), its paths made to reach
        # the carried meshes.
        mkdir -p "$carry/scenes/cornell-bunny" "$carry/scenes/cornell-box"
        cp scenes/cornell-box/cornell-box.* "$carry/scenes/cornell-box/"
        sed -e 's|mesh *= *"[./]*/shared/scenes/bunny/|mesh = "../bunny/|' \
            -e 's|mesh *= *"[./]*/scenes/cornell-box/|mesh = "../cornell-box/|' \
            reports/scenes/cornell-bunny/scene.toml > "$carry/scenes/cornell-bunny/scene.toml"
        # shellcheck disable=SC2086
        "$carry/cssm" bake "$carry/scenes/cornell-bunny" -o "$carry/bunny.cssm" $bake_bunny
    fi
    if [ -d "$carry/scenes/sibenik" ]; then
        mkdir -p "$carry/scenes/sibenik-view"
        cp reports/scenes/sibenik/scene.toml "$carry/scenes/sibenik-view/"
        sed -i 's|mesh = .*|mesh = "../sibenik/sibenik.obj"|' "$carry/scenes/sibenik-view/scene.toml"
    fi
    # GI scenes (Table 1: 128x128 texels): the Cornell box, the heads and the church at the
    # paper's 3,700 faces baked here; the full Sibenik cathedral is baked on the device (16
    # cores), its charts needing atlas 256.
    # shellcheck disable=SC2086
    "$carry/cssm" bake -o "$carry/cornell.cssm" $bake_cornell
    if [ -d "$carry/scenes/bunny" ] && [ -d "$carry/scenes/teapot" ]; then
        "$carry/cssm" report heads --scenes "$carry/scenes" --out "$carry/scenes/heads"
        # shellcheck disable=SC2086
        "$carry/cssm" bake "$carry/scenes/heads" -o "$carry/heads.cssm" $bake_table1
    fi
    if [ -d "$carry/scenes/sibenik" ]; then
        "$carry/cssm" report church --scenes "$carry/scenes" --out "$carry/scenes/church"
        # shellcheck disable=SC2086
        "$carry/cssm" bake "$carry/scenes/church" -o "$carry/church.cssm" $bake_table1
    fi
    # Pack what is large: the executables stripped (their line tables are for profiling here),
    # the scenes; the .cssm files are compressed already.
    local packed=()
    for exe in cssm gpu-limit $benches; do
        if [ -f "$carry/$exe" ]; then
            strip "$carry/$exe"
            packed+=("$exe")
        fi
    done
    XZ_OPT="-$xz_level -T0" tar -C "$carry" -cJf "$carry/pack.tar.xz" "${packed[@]}" scenes
    (cd "$carry" && rm -rf "${packed[@]}" scenes)
    du -sh "$carry"
}

# Unpacks $carry/pack.tar.xz where it is (once).
unpack() {
    [ -f "$carry/pack.tar.xz" ] || return 0
    if command -v xz > /dev/null; then
        tar -C "$carry" -xJf "$carry/pack.tar.xz"
    else
        python3 -c 'import sys, tarfile; tarfile.open(sys.argv[1]).extractall(sys.argv[2])' \
            "$carry/pack.tar.xz" "$carry"
    fi
    rm "$carry/pack.tar.xz"
}

measure() {
    if [ -d .gl ] && [ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ]; then
        for f in .gl/*.deb; do dpkg -x "$f" /; done
        ldconfig
        export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
        export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    fi
    unpack
    work=$(mktemp -d)
    # Results gather in $out and are packed into $OUT/runtime.tar.gz after every step.
    local back=${OUT:-/tmp/out}
    out=$work/runtime
    mkdir -p "$back" "$out"
    local budget=${MEASURE_BUDGET:-0} step_limit=${STEP_LIMIT:-0}
    failures=()
    # run NAME COMMAND...: the command's output into $out/runtime-NAME.txt; a failure is noted,
    # and every step's wall time goes to $out/runtime-steps.txt (to plan the next device call).
    run() {
        local name=$1 start=$SECONDS status=ok limit=$step_limit
        shift
        if [ "$budget" -gt 0 ]; then
            local left=$((budget - SECONDS))
            if [ $left -le 0 ]; then
                echo "$name 0 s SKIPPED (budget)" >> "$out/runtime-steps.txt"
                return 0
            fi
            if [ "$limit" -eq 0 ] || [ $left -lt "$limit" ]; then limit=$left; fi
        fi
        echo "== $name: $*"
        local cut=()
        [ "$limit" -gt 0 ] && cut=(timeout "$limit")
        if ! "${cut[@]}" "$@" 2>&1 | tee "$out/runtime-$name.txt"; then
            echo "== $name FAILED" | tee -a "$out/runtime-$name.txt"
            failures+=("$name")
            status=FAILED
        fi
        echo "$name $((SECONDS - start)) s $status" >> "$out/runtime-steps.txt"
        tar -C "$work" -czf "$back/runtime.tar.gz.part" runtime && mv "$back/runtime.tar.gz.part" "$back/runtime.tar.gz"
    }
    local c=$carry
    local sibenik=$c/scenes/sibenik-view
    # The bake on the GPU against the device's cores (issue 25): the same flags, whole process
    # (`total_seconds` of --json), the two files compared (byte for byte, or their runs). Arguments NAME:FLAGS,
    # the flags comma-separated; NAME is a carried scene or cornell-* (the built-in box).
    bakes_on_both() {
        local spec name flags scene device
        for spec in "$@"; do
            name=${spec%%:*} flags=${spec#*:} scene=""
            [[ $name == cornell-* ]] || scene=$c/scenes/$name
            if [ -n "$scene" ] && [ ! -d "$scene" ]; then continue; fi
            for device in gpu cpu; do
                # shellcheck disable=SC2086
                run "bake-$name-$device" "$c/cssm" bake $scene ${flags//,/ } --device $device \
                    -o "$work/bake-$name-$device.cssm" --json
            done
            # Byte for byte where the GPU rounds as the CPU does (lavapipe); otherwise (a GPU
            # that fuses multiply-adds may decide a ray through an edge otherwise:
            # reports/bake.md) the same runs to within 0.5%, as tests/gpu/depth_maps.rs holds
            # them off lavapipe.
            # shellcheck disable=SC2016
            run "bake-$name-same" bash -c '
                if cmp -s "$1" "$2"; then echo "identical"; exit 0; fi
                runs() { "$3" inspect "$1" | awk "/^ *runs /{print \$2}"; }
                g=$(runs "$1" "" "$3") c=$(runs "$2" "" "$3")
                echo "the files differ: $g runs on the GPU, $c on the CPU"
                awk -v g="$g" -v c="$c" "BEGIN { d = g / c - 1; exit !(d < 0.005 && d > -0.005) }"
            ' _ "$work/bake-$name-gpu.cssm" "$work/bake-$name-cpu.cssm" "$c/cssm"
            rm -f "$work/bake-$name-"*.cssm
        done
    }
    nvidia-smi -L > "$out/runtime-device.txt" 2>&1 || true
    # Does a GPU answer? One small image; nothing else runs if not.
    run adapter "$c/cssm" render --method direct --size 64x48 --timings --out "$out/adapter.png"
    if [ ${#failures[@]} -gt 0 ] ||
        { command -v nvidia-smi > /dev/null && ! grep -q NVIDIA "$out/runtime-adapter.txt"; }; then
        echo "no GPU adapter (or not the NVIDIA one): nothing measured" | tee "$out/runtime-failures.txt" >&2
        tar -C "$work" -czf "$back/runtime.tar.gz" runtime
        return 1
    fi
    # shellcheck disable=SC2086
    bakes_on_both $gpu_bakes
    # shellcheck disable=SC2086
    # With the cost model's check against the query before the lean rewrite (issue 48).
    run queries "$c/gpu_queries" --scenes "$c/scenes" $queries --only cornell-box,heads,church3700 \
        --h200 reports/h200-2026-12-04/runtime-queries.txt --csv "$out/runtime-queries.csv"
    if [ -x "$c/gpu-limit" ]; then
        # shellcheck disable=SC2086
        run gpu-limit "$c/gpu-limit" $limit_args
    fi
    # Moving objects' query throughput against the static query (issue 21, §3.3).
    # shellcheck disable=SC2086
    run moving-queries "$c/moving_queries" $moving --csv "$out/runtime-moving-queries.csv"
    # shellcheck disable=SC2086
    bakes_on_both $gpu_bakes_scenes
    # The persistent renderer's frame against a one-shot render (issue 16), with GPU ms per pass.
    # With the light moved before every frame too (issue 49: the CSSM methods' radiosity runs
    # in every frame then).
    # shellcheck disable=SC2086
    run frame-time "$c/frame_time" --size $frame_size --frames $frames --one-shots $one_shots \
        $frame_bake --moving-light \
        --out "$out/runtime-frame-time.md"
    # lightcuts' final gather in texture space against the walk it replaced (issue 49, item 2;
    # reports/final-gather.md), one bounce so that the builds' prepare passes stay short: the
    # frame is the final gather either way.
    # shellcheck disable=SC2086
    run frame-time-gather "$c/frame_time" --size $frame_size --frames $frames --one-shots 0 \
        $frame_bake --method lightcuts:gather=walk,bounces=1 --method lightcuts:bounces=1 \
        --method lightcuts:downsample=1,bounces=1 --method lightcuts:gather=walk,downsample=1,bounces=1 \
        --out "$out/runtime-frame-time-gather.md"
    # The radiosity's cached links against the walk with the light moved before every frame
    # (issue 49, item 1; reports/final-gather.md, "Radiosity with cached links").
    # shellcheck disable=SC2086
    run frame-time-links "$c/frame_time" --size $frame_size --frames $frames --one-shots 0 \
        $links_bake --moving-light --method lightmap --method lightmap:links=walk \
        --method lightcuts --method lightcuts:links=walk \
        --out "$out/runtime-frame-time-links.md"
    # Every method of the table in one persistent renderer at 1280x720: the frame time a window
    # of that size shows (issue 26), without the presentation.
    # shellcheck disable=SC2086
    run frame-time-all "$c/frame_time" --size $wide --frames $frames --one-shots $one_shots_all \
        $frame_bake --methods all $all_overrides --out "$out/runtime-frame-time-all.md"
    for size in $view_sizes; do
        run "direct-$size" "$c/cssm" render --method direct --size "$size" --timings \
            --out "$out/direct-$size.png"
    done
    # Global illumination, GPU ms per pass (Table 1): final gather (lightcuts) and the atlas
    # lightmap, 1 and 2 bounces; the bunny in the Cornell box as a moving object (issue 21),
    # its radiosity and final gather through the moving objects' query.
    gi() {
        local scene=$1 dir=$2 cssm=$3
        [ -f "$cssm" ] || { echo "no $scene: its GI rows are skipped"; return 0; }
        for method in lightcuts lightmap; do
            for bounces in 1 2; do
                local name=gi-$scene-$method-$bounces
                # shellcheck disable=SC2086
                run "$name" "$c/cssm" render $dir --cssm "$cssm" --method $method \
                    --bounces $bounces --size $gi_size --timings --out "$out/$name.png"
            done
        done
    }
    gi cornell "" "$c/cornell.cssm"
    gi bunny "$c/scenes/cornell-bunny" "$c/bunny.cssm"
    gi heads "$c/scenes/heads" "$c/heads.cssm"
    gi church "$c/scenes/church" "$c/church.cssm"
    # Every method of the table with timing rows (`MethodEntry::timing`: its paper's settings,
    # beside the methods it is compared with), static and moving light where its rows say, GPU
    # ms per pass: rsm with and without the micro linear buffer (issue 17; target: 1 ms at
    # 1280x720 with visibility), vct per voxel resolution (issue 18; target: 2 ms on the
    # Cornell box), ssil at Fig. 9's settings (issue 19; targets: 0.5 ms without, 1.5 ms with
    # visibility), vf at Table 1's marching sizes (issue 20; target: 2 ms on the Cornell box).
    local timed
    timed=$("$c/method_time" --list) || { failures+=("method_time --list"); timed=""; }
    for method in $timed; do
        for scene in cornell sibenik; do
            local scene_args=()
            if [ $scene = sibenik ]; then
                [ -d "$sibenik" ] || continue
                scene_args=(--scene "$sibenik")
            fi
            local sweep_name="sweep_${method}_${scene}" sweep_args=()
            if [ -n "${!sweep_name:-}" ]; then
                sweep_args=(--sweep "${!sweep_name}")
            fi
            # shellcheck disable=SC2086
            run "$method-$scene" "$c/method_time" --method "$method" "${scene_args[@]}" \
                "${sweep_args[@]}" --size $wide --frames $frames $shadow \
                --out "$out/runtime-$method-$scene.md"
        done
    done
    # vct's pools against a dense grid (Crassin et al. 2011 §10), per voxel resolution.
    run vct-pools-cornell "$c/vct_pools" --resolutions "${sweep_vct_cornell#resolution=}" \
        --out "$out/runtime-vct-pools-cornell.md"
    if [ -d "$sibenik" ]; then
        run vct-pools-sibenik "$c/vct_pools" --scene "$sibenik" \
            --resolutions "${sweep_vct_sibenik#resolution=}" --out "$out/runtime-vct-pools-sibenik.md"
    fi
    if [ -d "$c/scenes/sibenik" ]; then
        # shellcheck disable=SC2086
        run sibenik-bake "$c/cssm" bake "$c/scenes/sibenik" -o "$work/sibenik.cssm" $bake_sibenik
        # The Sibenik row of the query table, on that bake (the queries step has no time for
        # baking the cathedral itself).
        # shellcheck disable=SC2086
        run queries-sibenik "$c/gpu_queries" --scenes "$c/scenes" $queries --only sibenik \
            --baked "sibenik=$work/sibenik.cssm" --csv "$out/runtime-queries-sibenik.csv"
    fi
    gi sibenik "$c/scenes/sibenik" "$work/sibenik.cssm"
    # Every method side by side (issue 27): `cssm compare` on the built-in boxes, GPU ms per
    # pass and memory on the real GPU, the references path traced on the device's cores (the
    # longest step: last); the page stays in $work, its figures come back.
    # shellcheck disable=SC2086
    run compare "$c/cssm" compare $compare --out "$work/compare"
    for f in compare.md compare.csv compare.json chart.svg; do
        if [ -f "$work/compare/$f" ]; then cp "$work/compare/$f" "$out/"; fi
    done
    if [ ${#failures[@]} -gt 0 ]; then
        printf '%s\n' "${failures[@]}" > "$out/runtime-failures.txt"
    fi
    tar -C "$work" -czf "$back/runtime.tar.gz" runtime
    rm -rf "$work"
    if [ ${#failures[@]} -gt 0 ]; then
        echo "failed: ${failures[*]} (their output: runtime-NAME.txt in $back/runtime.tar.gz)" >&2
        return 1
    fi
}

case "${1:-}" in
prepare) prepare ;;
measure) measure ;;
smoke)
    small=1
    smoke=$(mktemp -d)
    trap 'rm -rf "$smoke"' EXIT
    CSSM_CARRY="$smoke/carry" OUT="$smoke/out" "$0" prepare --small
    CSSM_CARRY="$smoke/carry" OUT="$smoke/out" "$0" measure --small
    tar -C "$smoke" -xzf "$smoke/out/runtime.tar.gz"
    cat "$smoke/runtime/runtime-steps.txt"
    echo "runtime harness: every step ran ($(find "$smoke/runtime" -type f | wc -l) files)"
    ;;
*)
    echo "usage: $0 prepare|measure [--small] | smoke" >&2
    exit 2
    ;;
esac
