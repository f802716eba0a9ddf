#!/usr/bin/env bash
# The chunked bake's scaling on one machine (issue 25, reports/bake.md "Chunks on one machine"):
# one `cssm bake` against N chunk processes run side by side and `cssm merge`, whole wall time
# and the CPU time of all processes, the merged file compared with the single bake's.
#
#   reports/bake-chunks.sh [SCENE] [FLAGS...]    (default: the built-in Cornell box, atlas 512,
#                                                 cube 64: three segments of 65,536 maps)
# CHUNKS lists the N to try (default "2 3"). Prints a Markdown table.
#
# FARM=1 runs the chunks one after another instead, each alone on the machine, and reports what
# a farm of N such machines would take: the slowest chunk plus the merge (each term measured,
# their sum composed; the scheduler's own latency is not in it).
set -euo pipefail
cd "$(dirname "$0")/.."
cssm=${CSSM:-target/release/cssm}
scene=()
if [ $# -gt 0 ] && [ -d "$1" ]; then scene=("$1"); shift; fi
flags=("$@")
[ ${#flags[@]} -gt 0 ] || flags=(--atlas 512 --cube 64)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
now() { date +%s.%N; }
cpu() { awk '{print $14 + $15 + $16 + $17}' /proc/$$/stat; }
ticks=$(getconf CLK_TCK)

echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores"
echo "scene: ${scene[*]:-built-in Cornell box}, flags: ${flags[*]}"
echo
if [ -n "${FARM:-}" ]; then
    echo "| chunks | slowest chunk s | fastest chunk s | merge s | farm wall s (slowest + merge) | speed-up against one bake | file identical |"
    echo "| ---: | ---: | ---: | ---: | ---: | ---: | --- |"
else
    echo "| processes | wall s | CPU s (all processes) | wall against one bake | file identical |"
    echo "| ---: | ---: | ---: | ---: | --- |"
fi
c0=$(cpu); t0=$(now)
"$cssm" bake "${scene[@]}" "${flags[@]}" -o "$work/one.cssm" > /dev/null
t1=$(now); c1=$(cpu)
one=$(echo "$t1 - $t0" | bc -l)
if [ -n "${FARM:-}" ]; then
    printf '| 1 (one bake) | %.1f | %.1f | - | %.1f | 1.00 | - |\n' "$one" "$one" "$one"
else
    printf '| 1 (one bake) | %.1f | %.1f | 1.00 | - |\n' "$one" "$(echo "($c1 - $c0) / $ticks" | bc -l)"
fi
for n in ${CHUNKS:-2 3}; do
    if [ -n "${FARM:-}" ]; then
        slowest=0
        fastest=
        for ((i = 0; i < n; i++)); do
            t0=$(now)
            "$cssm" bake "${scene[@]}" "${flags[@]}" --chunk "$i/$n" -o "$work/part-$i" > /dev/null
            t1=$(now)
            chunk=$(echo "$t1 - $t0" | bc -l)
            if (($(echo "$chunk > $slowest" | bc -l))); then slowest=$chunk; fi
            if [ -z "$fastest" ] || (($(echo "$chunk < $fastest" | bc -l))); then fastest=$chunk; fi
        done
        t0=$(now)
        "$cssm" merge "$work"/part-* -o "$work/merged.cssm" > /dev/null
        t1=$(now)
        merge=$(echo "$t1 - $t0" | bc -l)
        farm=$(echo "$slowest + $merge" | bc -l)
        same=no
        cmp -s "$work/one.cssm" "$work/merged.cssm" && same=yes
        printf '| %d | %.1f | %.1f | %.1f | %.1f | %.2f | %s |\n' "$n" "$slowest" "$fastest" \
            "$merge" "$farm" "$(echo "$one / $farm" | bc -l)" "$same"
        rm -f "$work"/part-* "$work/merged.cssm"
        continue
    fi
    c0=$(cpu); t0=$(now)
    for ((i = 0; i < n; i++)); do
        "$cssm" bake "${scene[@]}" "${flags[@]}" --chunk "$i/$n" -o "$work/part-$i" > /dev/null &
    done
    wait
    "$cssm" merge "$work"/part-* -o "$work/merged.cssm" > /dev/null
    t1=$(now); c1=$(cpu)
    wall=$(echo "$t1 - $t0" | bc -l)
    same=no
    cmp -s "$work/one.cssm" "$work/merged.cssm" && same=yes
    printf '| %d chunks + merge | %.1f | %.1f | %.2f | %s |\n' "$n" "$wall" \
        "$(echo "($c1 - $c0) / $ticks" | bc -l)" "$(echo "$wall / $one" | bc -l)" "$same"
    rm -f "$work"/part-* "$work/merged.cssm"
done
