#!/usr/bin/env bash
# The soak: many consecutive demos on real processes, with two CPU-burning processes beside
# them, then QEMU demos. Prints `N runs, F failures` per group and the distribution of the
# first-motion latency (table activated -> first actuator moving, START included). Figures,
# not a test: a failure's output is kept under $SOAK_LOG for reading.
#
#   bench/soak.sh                 # 100 paint-robot runs, 20 lossy 5-actuator runs, 10 QEMU
#   SOAK_SCALE=10 bench/soak.sh   # a tenth of each (at least 1)
set -uo pipefail
cd "$(dirname "$0")/.."

scale=${SOAK_SCALE:-1}
runs() { local n=$(( $1 / scale )); echo $(( n < 1 ? 1 : n )); }
log=${SOAK_LOG:-$(mktemp -d)}
mkdir -p "$log"

cargo build -q --release -p config-tool
tool="${CARGO_TARGET_DIR:-target}/release/config-tool"

burners=()
for _ in 1 2; do
    ( while :; do :; done ) &
    burners+=($!)
done
trap 'kill "${burners[@]}" 2>/dev/null' EXIT

# group NAME RUNS ARGS...: runs `demo ARGS` RUNS times (seeds 1..RUNS); prints the failures
# and the first-motion latencies.
group() {
    local name=$1 n=$2
    shift 2
    local fails=0 lat=()
    for i in $(seq "$n"); do
        local out="$log/$name-$i.txt" code=0
        timeout 300 "$tool" demo "$@" --seed "$i" >"$out" 2>&1 || code=$?
        local t
        t=$(sed -n 's/^first motion of the cycle \([0-9.]*\) ms.*/\1/p' "$out" | head -1)
        [ -n "$t" ] && lat+=("$t")
        if [ "$code" = 0 ]; then
            rm -f "$out"
        else
            fails=$((fails + 1))
            echo "  $name run $i failed (exit $code): $out"
        fi
    done
    echo "$name: $n runs, $fails failures"
    if [ ${#lat[@]} -eq 0 ]; then
        echo "  no first-motion figure in any run: the demo's summary line changed"
    else
        printf '%s\n' "${lat[@]}" | sort -n | awk '
            { v[NR] = $1 }
            END {
                printf "  first motion (ms) over %d runs: min %.1f  median %.1f  p90 %.1f  max %.1f\n",
                    NR, v[1], v[int((NR + 1) / 2)], v[int(NR * 0.9 + 0.999)], v[NR]
            }'
    fi
}

echo "soak: 2 CPU burners beside every run; failures kept in $log"
group paint-robot "$(runs 100)" robot-configs/paint-robot.ron --cycles 1
group five-actuators-loss-0.2 "$(runs 20)" bench/robots/five-actuators.ron --cycles 1 --loss 0.2
if command -v qemu-system-arm >/dev/null; then
    (cd node-fw/boards/qemu-mps2 && cargo build -q --release)
    group qemu "$(runs 10)" robot-configs/paint-robot.ron --qemu --cycles 1
else
    echo "qemu: skipped (qemu-system-arm is not installed)"
fi
