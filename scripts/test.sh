#!/usr/bin/env bash
# The project's test command (README): every test of the workspace, release build.
# GPU tests need a Vulkan device; where none is installed this installs Mesa's lavapipe (a
# Vulkan implementation on the CPU), so the GPU tests run instead of failing; the page test
# needs Chromium and the window test Xvfb, installed the same way.
set -euo pipefail
cd "$(dirname "$0")/.."

has_vulkan_icd() {
    compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null ||
        compgen -G "/etc/vulkan/icd.d/*.json" >/dev/null ||
        [[ -n "${VK_DRIVER_FILES:-}${VK_ICD_FILENAMES:-}" ]]
}
SUDO=""
[[ $(id -u) -ne 0 ]] && SUDO="sudo"
if ! has_vulkan_icd; then
    echo "no Vulkan driver found: installing Mesa's lavapipe (mesa-vulkan-drivers)" >&2
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1
fi
# tests/view.rs opens `cssm view`'s window on a virtual X display (Xvfb, through xvfb-run);
# winit loads libxkbcommon-x11 for the keyboard.
if ! command -v xvfb-run >/dev/null 2>&1; then
    echo "no xvfb-run found: installing Xvfb (the window test, tests/view.rs)" >&2
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq xvfb xauth libxkbcommon-x11-0
fi
# tests/compare.rs opens `cssm compare`'s page in a real browser: Debian's Chromium, headless.
if [[ -z "${CSSM_CHROMIUM:-}" ]] && ! command -v chromium >/dev/null 2>&1; then
    echo "no Chromium found: installing Debian's chromium (the page test, tests/compare.rs)" >&2
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq chromium
fi

cargo test --workspace --release "$@"

# The libraries a user embeds compile no windowing, GUI or plotting crate: not cssm-bake or
# cssm-runtime, and not the `cssm` library without its default features (`viewer`, `lab`).
lean_check() {
    local heavy
    heavy="$(cargo tree --locked "$@" -e normal --prefix none |
        grep -E '^(winit|egui|egui-winit|egui-wgpu|plotters|nv-flip|meshopt|cssm-lab) ' || true)"
    if [[ -n "$heavy" ]]; then
        echo "cargo tree $*: a library pulls in the viewer or the lab:" >&2
        echo "$heavy" >&2
        exit 1
    fi
}
lean_check -p cssm-bake --features gpu
lean_check -p cssm-runtime
lean_check -p cssm --no-default-features

# The examples are a user's own packages outside the workspace, depending on cssm-bake and
# cssm-runtime by path: they must build and run as such (the target directory is shared, so
# their dependencies are the workspace's builds).
examples_out="$(mktemp -d)"
trap 'rm -rf "$examples_out"' EXIT
for example in bake-library embed-runtime; do
    CARGO_TARGET_DIR="$PWD/target" cargo build --release --locked \
        --manifest-path "examples/$example/Cargo.toml"
done
target/release/bake-library scenes/cornell-box "$examples_out/cornell-box.cssm"
# Mesa warns that XDG_RUNTIME_DIR is not set where no desktop session is (a headless render never
# needs it); the private directory quiets it, as `cssm` does for itself.
XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$examples_out}" target/release/embed-runtime scenes/cornell-box "$examples_out/cornell-box.cssm" \
    "$examples_out/embedded.png"
test -s "$examples_out/embedded.png"

# The batch farm of docs/batch-bake.md on a real scheduler: a single-node Slurm runs the docs' own
# job array and merge job, one task killed and retried (installs Slurm and munge where missing).
scripts/slurm_test.sh target/release/cssm

# The GPU benchmark harness (reports/runtime.sh: every benchmark and render the GPU machine runs)
# end to end at small sizes on this machine's device, so that no device time goes to a broken
# script.
reports/runtime.sh smoke
