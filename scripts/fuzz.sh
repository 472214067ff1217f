#!/usr/bin/env bash
# Runs the fuzz harness of tests/commands/fuzz/mod.rs for SECONDS (default 1800) from a random start seed (or
# SEED), at low priority. Failing inputs are kept in DIR (default target/fuzz-failures/) as
# fail-SEED.input; each is reproduced with
#   PLEXUS_FUZZ_SEED=SEED PLEXUS_FUZZ_CASES=1 cargo test --release --test commands fuzz::replay -- --ignored --nocapture
# Prints the number of cases run and every failure; exits non-zero when a case failed.
# PLEXUS_FUZZ_BINARY=PATH in the environment runs the binary cases against another plexus build.
#
# usage: scripts/fuzz.sh [SECONDS] [SEED] [DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-1800}"
seed="${2:-$(od -An -N6 -tu8 /dev/urandom | tr -d ' ')}"
keep="${3:-target/fuzz-failures}"
echo "fuzz: ${seconds} s from seed ${seed}; failing inputs go to ${keep}/" >&2
PLEXUS_FUZZ_SEED="$seed" PLEXUS_FUZZ_SECONDS="$seconds" PLEXUS_FUZZ_KEEP="$keep" \
    nice -n 10 cargo test --release --test commands fuzz::replay -- --ignored --nocapture 2>&1 |
    grep -E '^(fuzz:|FUZZ FAILURE|test result|thread .* panicked)' || true
# grep hides cargo's noise; the test's own verdict decides the exit code.
test "$(find "$keep" -name 'fail-*.input' 2>/dev/null | wc -l)" -eq 0
