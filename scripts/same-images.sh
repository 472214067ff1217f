#!/usr/bin/env bash
# Whether two plexus binaries render the same images, bit for bit: every integrator on a few shipped
# scenes at a sample budget. A refactor that must change no image (a rename, a new plug-in
# interface, a faster path through the same arithmetic) is checked against its parent's binary:
#
#   git worktree add --detach /tmp/parent HEAD~1 && (cd /tmp/parent && cargo build --release)
#   scripts/same-images.sh /tmp/parent/target/release/plexus target/release/plexus
#
# Options: --scenes a,b (names in scenes/, default below), --integrators a,b (default: all eight),
# --spp N (default 4), --size WxH (default 40x32: each scene's film is shrunk to it), --threads N
# (default 2), --seed S (default 7). Each render runs at max_depth 6. Prints "same SCENE INTEGRATOR"
# or "DIFF SCENE INTEGRATOR" per pair and exits 1 if any pair differs or a render fails.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() { sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; }
[[ $# -ge 1 && ( $1 == -h || $1 == --help ) ]] && { usage; exit 0; }
[[ $# -ge 2 ]] || { echo "same-images.sh: expected OLD_BINARY NEW_BINARY (--help)" >&2; exit 2; }
old=$1 new=$2
shift 2
scenes=cornell-box,cornell-glass,breakfast-window,veach-ajar,glass-prism,environment
integrators=pt,bdpt,light,pssmlt,mmlt,rjmlt,pmlt,emlt
spp=4 size=40x32 threads=2 seed=7
while [[ $# -gt 0 ]]; do
    case $1 in
        --scenes) scenes=$2; shift 2 ;;
        --integrators) integrators=$2; shift 2 ;;
        --spp) spp=$2; shift 2 ;;
        --size) size=$2; shift 2 ;;
        --threads) threads=$2; shift 2 ;;
        --seed) seed=$2; shift 2 ;;
        *) echo "same-images.sh: unknown option '$1' (--help)" >&2; exit 2 ;;
    esac
done
for bin in "$old" "$new"; do
    [[ -x $bin ]] || { echo "same-images.sh: no executable at '$bin'" >&2; exit 2; }
done
width=${size%x*} height=${size#*x}

out=$(mktemp -d)
# The shrunk scene copies sit beside the originals, so that their relative mesh and texture paths
# still resolve; they are removed on exit.
copies=()
cleanup() { rm -rf "$out"; rm -f "${copies[@]}"; }
trap cleanup EXIT

status=0
IFS=, read -ra scene_list <<< "$scenes"
IFS=, read -ra integrator_list <<< "$integrators"
for scene in "${scene_list[@]}"; do
    [[ -f scenes/$scene.toml ]] || { echo "same-images.sh: no scene scenes/$scene.toml" >&2; exit 2; }
    copy=scenes/.same-images-$$-$scene.toml
    copies+=("$copy")
    sed -E "s/^resolution = \[[0-9]+, *[0-9]+\]/resolution = [$width, $height]/" "scenes/$scene.toml" > "$copy"
    for integrator in "${integrator_list[@]}"; do
        for which in old new; do
            bin=$old
            [[ $which == new ]] && bin=$new
            if ! "$bin" render "$copy" --integrator "$integrator" --spp "$spp" --seed "$seed" \
                --threads "$threads" --set max_depth=6 -o "$out/$which.exr" > "$out/$which.log" 2>&1; then
                echo "FAIL $scene $integrator ($which binary): $(tail -n 1 "$out/$which.log")"
                status=1
                continue 2
            fi
        done
        if cmp -s "$out/old.exr" "$out/new.exr"; then
            echo "same $scene $integrator"
        else
            echo "DIFF $scene $integrator"
            status=1
        fi
    done
done
exit $status
