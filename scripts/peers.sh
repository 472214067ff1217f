#!/bin/sh
# plexus's path tracer against Mitsuba 3 (llvm_ad_rgb) at equal samples and equal time on the
# Cornell box, its glossy and glass variants and the door (scripts/peers.py explains the measure).
# Sets up a virtual environment with Mitsuba 3 in target/peersenv on first use; llvm_ad_rgb needs
# Debian's libllvm19 (apt-get install libllvm19), found through DRJIT_LIBLLVM_PATH.
#
# Usage: scripts/peers.sh [peers.py options, e.g. --spp 64 --renders 4]
# The binary is $PLEXUS if set, else the release build (built here if missing); the scenes' XML is
# in scenes/mitsuba/. docs/lab/benchmarks-history.md ("plexus against Mitsuba 3") holds the table.
set -eu
cd "$(dirname "$0")/.."
if [ -z "${PLEXUS:-}" ]; then
    cargo build --release --quiet
    PLEXUS="$(pwd)/${CARGO_TARGET_DIR:-target}/release/plexus"
fi
export PLEXUS
VENV="${PEERS_VENV:-target/peersenv}"
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet mitsuba numpy
fi
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
    for lib in /usr/lib/x86_64-linux-gnu/libLLVM-19.so /usr/lib/llvm-19/lib/libLLVM-19.so; do
        if [ -e "$lib" ]; then DRJIT_LIBLLVM_PATH=$lib; fi
    done
fi
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
    echo "peers.sh: libLLVM-19.so not found: apt-get install libllvm19, or set DRJIT_LIBLLVM_PATH" >&2
    exit 2
fi
export DRJIT_LIBLLVM_PATH
exec "$VENV/bin/python" scripts/peers.py "$@"
