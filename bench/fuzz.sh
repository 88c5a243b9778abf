#!/usr/bin/env bash
# Coverage-guided fuzzing (cargo-fuzz, libFuzzer; on nightly) of everything read from
# outside: `table` (a table payload as a node decodes and validates it, its round trip and
# the engine run over it), `node_frames` (frames from the air into a running node's core and
# into an unconfigured node that stages and activates what it is sent), `wire` (every wire
# reader: MAC frames, messages, the link's fast reader held to the codec, the medium's
# deframer, security, key blocks, deployment slots), `robot_ron` (a robot file through
# `compile`) and `iec61499_xml` (each XML reader, and the 4diac paint robot compiled with
# its VC type or its application replaced by the text). Seeds: every robot in robot-configs/ and bench/robots/, compiled to tables
# for `table`. A failure is a bug found: libFuzzer prints the input it saved under
# fuzz/artifacts/TARGET/; make it a test beside the code it breaks, then fix.
#
#   bench/fuzz.sh                       # every target 60 s
#   FUZZ_SECONDS=600 bench/fuzz.sh table node_frames
#
# Needs: rustup toolchain install nightly; cargo install cargo-fuzz.
set -euo pipefail
cd "$(dirname "$0")/.."

each=${FUZZ_SECONDS:-60}
if ! command -v cargo-fuzz >/dev/null; then
    echo "fuzz: cargo-fuzz is not installed (cargo install cargo-fuzz; nightly Rust)" >&2
    exit 1
fi
if [ $# -eq 0 ]; then
    set -- table node_frames wire robot_ron iec61499_xml
fi

# Seeds: the robots, and each role's table payload (the blob without its 8-byte header
# and 4-byte CRC trailer).
mkdir -p fuzz/corpus/robot_ron fuzz/corpus/table fuzz/corpus/iec61499_xml
cp robot-configs/*.ron bench/robots/*.ron fuzz/corpus/robot_ron/
# The XML target's first byte says which file the text replaces (even: the VC type, odd:
# the application).
for xml in robot-compiler/types/iec61499/*.fbt robot-configs/4diac/*/*.fbt tests/fixtures/4diac/*/*.fbt; do
    { printf '\000'; cat "$xml"; } >"fuzz/corpus/iec61499_xml/$(basename "$(dirname "$xml")")-$(basename "$xml")"
done
for xml in robot-configs/4diac/*/*.sys tests/fixtures/4diac/*/*.sys; do
    { printf '\001'; cat "$xml"; } >"fuzz/corpus/iec61499_xml/$(basename "$(dirname "$xml")")-$(basename "$xml")"
done
cargo build -q -p config-tool
blobs=$(mktemp -d)
trap 'rm -rf "$blobs"' EXIT
for robot in robot-configs/*.ron; do
    name=$(basename "$robot" .ron)
    target/debug/config-tool compile --out "$blobs/$name" "$robot" >/dev/null 2>&1
    for blob in "$blobs/$name"/*.bin; do
        tail -c +9 "$blob" | head -c -4 >"fuzz/corpus/table/$name-$(basename "$blob")"
    done
done

# `node_frames`: the frames a push and a cycle put on the air for the paint robot's VC node
# (0x0011), from a demo's capture with security off (the fuzzed nodes hold no keys), as
# two inputs: every frame to the unconfigured node, and every frame to the running one.
sed 's/^    name: "paint-robot",/&\n    security: Off,/' robot-configs/paint-robot.ron >"$blobs/paint-robot.ron"
target/debug/config-tool demo "$blobs/paint-robot.ron" --cycles 1 --no-reconfigure \
    --pcap "$blobs/air.pcap" >/dev/null 2>&1
mkdir -p fuzz/corpus/node_frames
python3 - "$blobs/air.pcap" fuzz/corpus/node_frames/paint-robot <<'PY'
import struct, sys
pcap, out = sys.argv[1], sys.argv[2]
b = open(pcap, "rb").read()
e = "<" if b[:4] == b"\xd4\xc3\xb2\xa1" else ">"
link = struct.unpack(e + "I", b[20:24])[0]
fresh, running, at = bytearray(), bytearray(), 24
while at + 16 <= len(b):
    n = struct.unpack(e + "I", b[at + 8 : at + 12])[0]
    frame, at = b[at + 16 : at + 16 + n], at + 16 + n
    mpdu = frame[:-2] if link == 195 else frame  # 195: with its FCS
    if 9 <= len(mpdu) <= 127 and struct.unpack("<H", mpdu[5:7])[0] in (0x0011, 0xFFFF):
        # A frame to the node (`1`: the unconfigured one, `0`: the running one), then the
        # clock on by 21 ms.
        fresh += bytes([1, len(mpdu)]) + mpdu + bytes([2, 3])
        running += bytes([0, len(mpdu)]) + mpdu + bytes([2, 3])
open(out + "-fresh", "wb").write(fresh)
open(out + "-running", "wb").write(running)
PY

for target in "$@"; do
    echo "fuzz: $target for ${each} s"
    (cd fuzz && cargo +nightly fuzz run "$target" -- \
        -max_total_time="$each" -timeout=10 -rss_limit_mb=4096 -print_final_stats=1 2>&1) |
        grep -E '^(stat::number_of_executed_units|stat::peak_rss_mb)|ERROR|SUMMARY|panicked' || true
    if [ -n "$(ls -A "fuzz/artifacts/$target" 2>/dev/null)" ]; then
        echo "fuzz: $target FAILED: fuzz/artifacts/$target/ holds the input" >&2
        exit 1
    fi
done
echo "fuzz: no failure"
