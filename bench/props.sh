#!/usr/bin/env bash
# Draws fresh property-test cases, run after run: CI draws one set per commit (seeded by its
# hash, .ci/run), this explores further. Each run gets a random PROPTEST_RNG_SEED, printed,
# so a failing run is repeated exactly with that seed (and proptest writes the failing
# case to the `*.proptest-regressions` file beside its test: commit it with the fix).
#
#   bench/props.sh            # 5 runs of the crates with property tests
#   RUNS=20 bench/props.sh
#   RUNS=3 bench/props.sh -p config-schema   # other `cargo test` arguments
set -euo pipefail
cd "$(dirname "$0")/.."

runs=${RUNS:-5}
if [ $# -eq 0 ]; then
    set -- -p config-schema -p node-fw -p robot-analysis -p robot-compiler
fi
cargo test -q --no-run "$@"
log=$(mktemp)
trap 'rm -f "$log"' EXIT

failed=0
for i in $(seq 1 "$runs"); do
    seed=$(od -An -N8 -tu8 /dev/urandom | tr -d ' ')
    if PROPTEST_RNG_SEED=$seed cargo test -q "$@" >"$log" 2>&1; then
        echo "run $i of $runs: PROPTEST_RNG_SEED=$seed: passed"
    else
        failed=$((failed + 1))
        echo "run $i of $runs: PROPTEST_RNG_SEED=$seed: FAILED"
        grep -E "^test .* FAILED|panicked|minimal failing input" "$log" | head -20
        echo "  repeat: PROPTEST_RNG_SEED=$seed cargo test $*"
    fi
done
echo "property tests: $runs runs, $failed failed"
[ "$failed" -eq 0 ]
