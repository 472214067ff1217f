# Sourced by the benchmark scripts: sets `plexus` to the binary they measure and checks their scene.
#
#   source "$(dirname "$0")/plexus-binary.sh"
#   plexus_binary SCRIPT-NAME [SCENE]
#
# The binary is $PLEXUS if set, else $CARGO_TARGET_DIR/release/plexus, else target/release/plexus.
# A missing binary or scene ends the script with a one-line error naming it (exit 1).
plexus_binary() {
    local name=$1 scene=${2:-}
    if [[ -n "${PLEXUS:-}" ]]; then
        plexus=$PLEXUS
    elif [[ -n "${CARGO_TARGET_DIR:-}" ]]; then
        plexus=$CARGO_TARGET_DIR/release/plexus
    else
        plexus=target/release/plexus
    fi
    if [[ ! -x "$plexus" ]]; then
        echo "$name: no plexus binary at '$plexus' (build with 'cargo build --release' or set PLEXUS)" >&2
        exit 1
    fi
    if [[ -n "$scene" && ! -f "$scene" ]]; then
        echo "$name: scene '$scene' not found" >&2
        exit 1
    fi
}
