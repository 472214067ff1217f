#!/bin/sh
# Regenerates docs/benchmarks.md's measured sections: every integrator at equal time on six shipped
# scenes, against the path-traced references in references/ (scripts/make-references.sh), rendered
# at each reference's resolution and with its max_depth (8, the MLT papers' L), so that a measured
# error is noise and not a difference in which paths are counted.
#
# Usage: scripts/benchmarks.sh [--scenes LIST] [--integrators LIST] [--times LIST] [--seeds N]
#                              [--threads N] [--page-only]
#   --scenes       comma-separated, from: cornell-box, cornell-glossy, cornell-glass, veach-ajar,
#                  breakfast-window, staircase (default: all six). Only these scenes are rendered and
#                  only their sections of the page (and their summary rows) change.
#   --integrators  comma-separated, or all (default: all eight `plexus converge` knows)
#   --times        equal-time budgets in seconds (default: 3,10)
#   --seeds        seeds per integrator and budget, 0 .. N-1 (default: 3)
#   --threads      worker threads (default: 2)
#   --page-only    render nothing; rewrite the page's generated sections from docs/bench/
# With the defaults a full run renders 6 scenes x 8 integrators x 3 seeds x (3 + 10) s = 31 min
# (32 min of wall time with the scenes' loading, whatever the load: the budgets are wall time).
#
# Writes docs/bench/<scene>-converge.{csv,md} (`plexus converge`'s rows and tables),
# docs/img/<scene>-converge.png (its plot), one line per scene in docs/bench/machine.txt (the
# commit, whether the build inputs were modified, the machine, and the load during that scene's
# run), and then the generated sections of docs/benchmarks.md (scripts/benchmarks_page.py).
# The binary is $PLEXUS if set, else the release build of this tree (built here). Either way it is
# copied first, so a rebuild of target/ during the run cannot change the binary between scenes.
set -eu
cd "$(dirname "$0")/.."

ALL_SCENES="cornell-box cornell-glossy cornell-glass veach-ajar breakfast-window staircase"
# The scene file of each benchmark scene; its reference is references/<name>.exr, whose resolution
# `plexus converge` renders at, and references/<name>.json records how it was made.
scene_file() {
    case "$1" in
        staircase) echo scenes/imported/staircase.toml ;;
        *) echo "scenes/$1.toml" ;;
    esac
}

SCENES="$ALL_SCENES"
INTEGRATORS=all
TIMES=3,10
SEEDS=3
THREADS=2
PAGE_ONLY=no
MAX_DEPTH=8
while [ $# -gt 0 ]; do
    case "$1" in
        --scenes) SCENES=$(echo "$2" | tr ',' ' '); shift 2 ;;
        --integrators) INTEGRATORS="$2"; shift 2 ;;
        --times) TIMES="$2"; shift 2 ;;
        --seeds) SEEDS="$2"; shift 2 ;;
        --threads) THREADS="$2"; shift 2 ;;
        --page-only) PAGE_ONLY=yes; shift ;;
        -h|--help) sed -n '2,/^set -eu/p' "$0" | sed '$d'; exit 0 ;;
        *) echo "scripts/benchmarks.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done
for scene in $SCENES; do
    case " $ALL_SCENES " in
        *" $scene "*) ;;
        *) echo "scripts/benchmarks.sh: unknown scene '$scene' (one of: $ALL_SCENES)" >&2; exit 2 ;;
    esac
done
command -v python3 >/dev/null 2>&1 || { echo "scripts/benchmarks.sh: python3 is needed for the page" >&2; exit 1; }

if [ "$PAGE_ONLY" = no ]; then
    # Every reference must have been made at the depth every integrator renders with.
    for scene in $SCENES; do
        ref="references/$scene.json"
        [ -f "references/$scene.exr" ] && [ -f "$ref" ] || { echo "missing references/$scene.{exr,json}" >&2; exit 1; }
        depth=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["settings"]["max_depth"])' "$ref")
        [ "$depth" = "$MAX_DEPTH" ] || { echo "$ref: max_depth $depth, the benchmark renders $MAX_DEPTH" >&2; exit 1; }
        [ -f "$(scene_file "$scene")" ] || { echo "missing $(scene_file "$scene")" >&2; exit 1; }
    done

    work=$(mktemp -d)
    sampler=""
    cleanup() {
        [ -n "$sampler" ] && kill "$sampler" 2>/dev/null || true
        rm -rf "$work"
    }
    trap cleanup EXIT
    trap 'exit 130' INT TERM
    # What the binary was built from: HEAD, and whether any build input (or scene, or reference)
    # differs from it. With $PLEXUS set, the binary may come from elsewhere: the page says so.
    commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
    if [ "$commit" = unknown ]; then
        dirty=unknown
    elif [ -n "$(git status --porcelain -- src ffi build.rs Cargo.toml Cargo.lock scenes references)" ]; then
        dirty=yes
    else
        dirty=no
    fi
    if [ -z "${PLEXUS:-}" ]; then
        cargo build --release --quiet
        PLEXUS="${CARGO_TARGET_DIR:-target}/release/plexus"
    else
        commit="$commit, binary \$PLEXUS=$PLEXUS"
    fi
    cp "$PLEXUS" "$work/plexus"
    cpu_model=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)
    cores=$(nproc)
    mem_gib=$(awk '/MemTotal/ {printf "%.0f", $2 / 1048576}' /proc/meminfo)
    ticks=$(getconf CLK_TCK)
    mkdir -p docs/bench docs/img
    [ -f docs/bench/machine.txt ] || printf '%s\n' \
        "# scripts/benchmarks.sh: one line per scene, its latest run (tab-separated; read by scripts/benchmarks_page.py)" \
        "$(printf 'scene\tcommit\tdirty\tdate\tcpu\tcores\tmem_gib\tthreads\ttimes\tseeds\tintegrators\twall_s\tcpu_s\tload_start\tload_mean\tload_max')" \
        > docs/bench/machine.txt

    # CPU seconds used by this shell's finished children (utime + stime of the waited-for ones).
    children_cpu_ticks() { sed 's/.*) //' /proc/$$/stat | awk '{print $14 + $15}'; }
    for scene in $SCENES; do
        # The 1-minute load average every 10 s while the scene renders.
        : > "$work/load"
        (while :; do cut -d' ' -f1 /proc/loadavg >> "$work/load"; sleep 10; done) &
        sampler=$!
        load_start=$(cut -d' ' -f1 /proc/loadavg)
        date=$(date -u +%Y-%m-%dT%H:%MZ)
        cpu_before=$(children_cpu_ticks)
        wall_before=$(cut -d' ' -f1 /proc/uptime)
        "$work/plexus" converge "$(scene_file "$scene")" --reference "references/$scene.exr" \
            --integrators "$INTEGRATORS" --times "$TIMES" --seeds "$SEEDS" --threads "$THREADS" \
            --set max_depth=$MAX_DEPTH --out-dir docs/bench
        wall_s=$(awk -v a="$wall_before" -v b="$(cut -d' ' -f1 /proc/uptime)" 'BEGIN {printf "%.0f", b - a}')
        cpu_s=$(awk -v a="$cpu_before" -v b="$(children_cpu_ticks)" -v t="$ticks" 'BEGIN {printf "%.1f", (b - a) / t}')
        kill "$sampler" 2>/dev/null || true
        wait "$sampler" 2>/dev/null || true
        sampler=""
        mv "docs/bench/$scene-converge.png" "docs/img/$scene-converge.png"
        load_mean=$(awk '{s += $1; n++} END {printf "%.2f", n ? s / n : 0}' "$work/load")
        load_max=$(sort -g "$work/load" | tail -n 1)
        line=$(printf '%s\t' "$scene" "$commit" "$dirty" "$date" "$cpu_model" "$cores" "$mem_gib" "$THREADS" \
            "$TIMES" "$SEEDS" "$INTEGRATORS" "$wall_s" "$cpu_s" "$load_start" "$load_mean")
        line="$line${load_max:-$load_start}"
        # Replace the scene's line, or append it; the other scenes' lines stay as they are.
        awk -F '\t' -v scene="$scene" -v line="$line" '
            $1 == scene { print line; done = 1; next } { print } END { if (!done) print line }' \
            docs/bench/machine.txt > "$work/machine.txt"
        cat "$work/machine.txt" > docs/bench/machine.txt
        echo "$scene: ${wall_s} s, ${cpu_s} CPU s, load average $load_start at the start, mean $load_mean" >&2
    done
fi

# shellcheck disable=SC2086 # the scene list is split on purpose
python3 scripts/benchmarks_page.py $SCENES
echo "docs/benchmarks.md: generated sections rewritten for: $SCENES; revisit its 'Reading' against the new numbers" >&2
