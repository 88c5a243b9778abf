#!/usr/bin/env bash
# Instructions per stimulus of the table interpreter on x86-64, counted by callgrind (exact,
# not timed: the same on a loaded machine). Each figure is a difference: the run with 2N
# stimuli minus the run with N, divided by N, so start-up, compiling the robot and building
# the table are taken out.
#
#   bench/instructions.sh          # N = 2000 (valgrind: apt-get install valgrind)
#   N=500 bench/instructions.sh
#
# Figures: the IEC 61499 up-counter E_CTU as an explicit chart (bench/robots/e-ctu.ron),
# per pulse, one chart and two in series (the second counting the first's CUO; the
# difference is what one more chart in a chain costs), its effects taken as a node takes
# them (no trace of each transition: the node keeps none), then the same with the trace
# sink the VC figures use; the paper robot's VC chart per
# stimulus (one cycle as its node sees it: 18 input edges and remote events), interpreted
# and hand-written as a `match` (tests/src/vc_dispatch.rs), and their ratio. Then the whole
# node core (`NodeCore`, unsecured, every frame delivered): a button on node A published to
# node B, whose chart toggles a lamp, counted only inside one call of the core each (A's
# input edge, A told a level it has, B receiving the event, A receiving B's ack); then the
# same two nodes with link keys, their events and acks secured (ENC-MIC-64), as a
# machine's nodes run by default.
set -euo pipefail
cd "$(dirname "$0")/.."

n=${N:-2000}
if ! command -v valgrind >/dev/null; then
    echo "instructions: valgrind is not installed (apt-get install valgrind)" >&2
    exit 1
fi
cargo build -q --release -p robot-tests --example instructions
bin="${CARGO_TARGET_DIR:-target}/release/examples/instructions"

# instructions RUN COUNT: the instructions callgrind counted for `bin RUN COUNT`
count() {
    valgrind --tool=callgrind --callgrind-out-file=/dev/null "$bin" "$1" "$2" 2>&1 >/dev/null |
        awk '/Collected :/ { print $NF }'
}

# inside FN COUNT [RUN]: the instructions callgrind counted inside `node::FN` of
# `bin RUN COUNT` (RUN: node, the default, or node-secured)
inside() {
    valgrind --tool=callgrind --callgrind-out-file=/dev/null --toggle-collect="*node::$1" \
        "$bin" "${3:-node}" "$2" 2>&1 >/dev/null | awk '/Collected :/ { print $NF }'
}

# per_call FN UNITS [RUN]: instructions per call of `node::FN`, UNITS calls per press
per_call() {
    local a b
    a=$(inside "$1" "$n" "${3:-node}")
    b=$(inside "$1" $((2 * n)) "${3:-node}")
    awk -v a="$a" -v b="$b" -v n="$n" -v u="$2" 'BEGIN { printf "%.1f", (b - a) / (n * u) }'
}

# per RUN UNITS: instructions per stimulus of RUN, whose COUNT is in units of UNITS stimuli
per() {
    local a b
    a=$(count "$1" "$n")
    b=$(count "$1" $((2 * n)))
    awk -v a="$a" -v b="$b" -v n="$n" -v u="$2" 'BEGIN { printf "%.1f", (b - a) / (n * u) }'
}

ctu1=$(per ctu1 1)
ctu2=$(per ctu2 1)
ctu1t=$(per ctu1-trace 1)
ctu2t=$(per ctu2-trace 1)
vc=$(per vc 18)
hand=$(per vc-hand 18)

printf 'instructions per stimulus (callgrind, x86-64, release; N = %d)\n' "$n"
printf '  E_CTU, one chart          %8s per pulse\n' "$ctu1"
printf '  E_CTU, two in series      %8s per pulse\n' "$ctu2"
awk -v a="$ctu1" -v b="$ctu2" 'BEGIN { printf "  one more chart in series  %8.1f per pulse  (target: under 100)\n", b - a }'
printf '  the same, each transition traced (the sink below; a node keeps no trace)\n'
printf '    E_CTU, one chart        %8s per pulse\n' "$ctu1t"
printf '    E_CTU, two in series    %8s per pulse\n' "$ctu2t"
awk -v a="$ctu1t" -v b="$ctu2t" 'BEGIN { printf "    one more chart          %8.1f per pulse\n", b - a }'
printf '  VC chart, interpreted     %8s per stimulus\n' "$vc"
printf '  VC chart, hand-written    %8s per stimulus\n' "$hand"
awk -v a="$vc" -v b="$hand" 'BEGIN { printf "  interpreted / hand        %8.2fx  (target: within 1.5x)\n", a / b }'
echo "  (Eclipse 4diac FORTE's E_CTU, measured the same way for the issue: 313 per event)"

printf 'instructions per call inside the node core (NodeCore, unsecured)\n'
printf '  input edge on A (publishes on rise)   %8s\n' "$(per_call a_edge 2)"
printf '  input level A has already             %8s\n' "$(per_call a_level 2)"
printf '  event received by B (ack, chart)      %8s  (target: under 300)\n' "$(per_call b_event 1)"
printf '  ack received by A                     %8s\n' "$(per_call a_ack 1)"

printf 'the same with link keys (events and acks secured at ENC-MIC-64, as machines run by\n'
printf 'default; the aes crate takes the CPU'"'"'s AES instructions: a hardware AES, as the\n'
printf 'nRF52840'"'"'s ECB unit)\n'
printf '  input edge on A (publishes on rise)   %8s\n' "$(per_call a_edge 2 node-secured)"
printf '  event received by B (ack, chart)      %8s\n' "$(per_call b_event 1 node-secured)"
printf '  ack received by A                     %8s\n' "$(per_call a_ack 1 node-secured)"
