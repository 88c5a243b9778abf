#!/usr/bin/env bash
# Flash and static RAM of both release firmware images (QEMU mps2-an385 and nRF52840),
# broken down by section, with the table capacities they were built with.
#
#   bench/footprint.sh            # builds both images (release), prints the figures
#   bench/footprint.sh --no-build # only measures what is built
#
# Flash = vector table + .text + .rodata + .data (its initial values live in flash);
# static RAM = .data + .bss + .uninit (the stack is not counted: it gets the rest of RAM).
# Targets for the nRF52840 image: flash < 48 KiB, static RAM < 16 KiB; frame security adds
# < 8 KiB of flash (against the same image built without it: --no-default-features, its
# own build directory).
set -euo pipefail
cd "$(dirname "$0")/.."

BOARDS="node-fw/boards"
QEMU_ELF="$BOARDS/target/thumbv7m-none-eabi/release/qemu-mps2"
NRF_ELF="$BOARDS/target/thumbv7em-none-eabihf/release/nrf52840"
# The same node without frame security (feature `frame-security` off: `runtime::run`, no
# key, no frame counter, the crypto not linked): what security costs, not for a machine.
NRF_UNSECURED_DIR="$BOARDS/target/unsecured"
NRF_UNSECURED_ELF="$NRF_UNSECURED_DIR/thumbv7em-none-eabihf/release/nrf52840"

if [ "${1:-}" != "--no-build" ]; then
    # The boards' own target directory (a CARGO_TARGET_DIR set in the shell would build
    # them elsewhere, and the figures below would be of images built before).
    (cd "$BOARDS/qemu-mps2" && env -u CARGO_TARGET_DIR cargo build --release --locked -q)
    (cd "$BOARDS/nrf52840" && env -u CARGO_TARGET_DIR cargo build --release --locked -q)
    (cd "$BOARDS/nrf52840" && CARGO_TARGET_DIR=../target/unsecured \
        cargo build --release --locked -q --no-default-features)
fi

# An llvm-size: on PATH, or rustup's llvm-tools.
SIZE=""
for c in llvm-size rust-size arm-none-eabi-size; do
    if command -v "$c" >/dev/null; then SIZE="$c"; break; fi
done
if [ -z "$SIZE" ]; then
    rustup component add llvm-tools >/dev/null 2>&1 || true
    SIZE="$(find "$(rustc --print sysroot)" -name llvm-size -type f | head -n 1)"
fi
if [ -z "$SIZE" ]; then
    echo "footprint: no llvm-size (rustup component add llvm-tools)" >&2
    exit 1
fi

# section sizes of ELF $1 as "name size" lines
sections() { "$SIZE" -A "$1" | awk 'NR > 2 && NF >= 2 { print $1, $2 }'; }

report() {
    local name="$1" elf="$2" flash_max="$3" ram_max="$4"
    sections "$elf" | awk -v name="$name" -v fmax="$flash_max" -v rmax="$ram_max" '
        { s[$1] = $2 }
        END {
            vt = s[".vector_table"] + 0; text = s[".text"] + 0; ro = s[".rodata"] + 0
            data = s[".data"] + 0; bss = s[".bss"] + 0; un = s[".uninit"] + 0
            flash = vt + text + ro + data; ram = data + bss + un
            printf "%-11s %7d %7d %7d %6d %7d %7d  %8d (%5.1f KiB) %7d (%5.1f KiB)\n", \
                name, vt, text, ro, data, bss, un, flash, flash / 1024, ram, ram / 1024
            if (fmax > 0) {
                printf "%-11s target: flash < %d KiB: %s; static RAM < %d KiB: %s\n", "", \
                    fmax, (flash < fmax * 1024 ? "met" : "MISSED"), \
                    rmax, (ram < rmax * 1024 ? "met" : "MISSED")
            }
        }'
}

echo "release images (bytes)"
printf "%-11s %7s %7s %7s %6s %7s %7s  %20s %21s\n" image vectors text rodata data bss uninit "flash" "static RAM"
report qemu-mps2 "$QEMU_ELF" 0 0
report nrf52840 "$NRF_ELF" 48 16
report "nrf-nosec" "$NRF_UNSECURED_ELF" 0 0

# flash of ELF $1 (as report counts it)
flash_of() {
    sections "$1" | awk '{ s[$1] = $2 }
        END { print s[".vector_table"] + s[".text"] + s[".rodata"] + s[".data"] }'
}
secured="$(flash_of "$NRF_ELF")"
unsecured="$(flash_of "$NRF_UNSECURED_ELF")"
awk -v s="$secured" -v u="$unsecured" 'BEGIN {
    d = s - u
    printf "frame security adds %d B of flash (%.1f KiB) to the nrf52840 image (%d without it)\n", \
        d, d / 1024, u
    printf "%-11s target: < 8 KiB added: %s\n", "", (d < 8 * 1024 ? "met" : "MISSED")
}'

# Panic locations carry their source file's path, those of the checkout's own crates with
# the checkout's directory in it. The figure above is independent of where the checkout
# lives only if both images name the same checkout files (each path is stored once per
# image); a file named by one image only moves the figure with the directory's length.
OBJCOPY=""
for c in "$(dirname "$(command -v "$SIZE" || echo "$SIZE")")/llvm-objcopy" llvm-objcopy; do
    if command -v "$c" >/dev/null; then OBJCOPY="$c"; break; fi
done
# checkout files named in the read-only data of ELF $1, one a line
checkout_paths() {
    local ro
    ro="$(mktemp)"
    "$OBJCOPY" -O binary --only-section=.rodata "$1" "$ro"
    tr -c '[:print:]' '\n' <"$ro" | awk -v root="$PWD/" '{
            while ((i = index($0, root)) > 0) {
                $0 = substr($0, i + length(root))
                if (match($0, /^([A-Za-z0-9_-]+\/)*[A-Za-z0-9_-]+\.rs/)) print substr($0, 1, RLENGTH)
            }
        }' | sort -u
    rm -f "$ro"
}
if [ -n "$OBJCOPY" ]; then
    only="$(comm -3 <(checkout_paths "$NRF_ELF") <(checkout_paths "$NRF_UNSECURED_ELF") |
        tr -d '\t' | tr '\n' ' ')"
    if [ -z "$only" ]; then
        echo "            both images name the same checkout files: the figure does not depend on the checkout's path"
    else
        echo "            DEPENDS ON THE CHECKOUT'S PATH: named by one image only: $only"
    fi
fi

echo
echo "largest static RAM objects (nrf52840)"
nm -S --size-sort -C -t d "$NRF_ELF" 2>/dev/null | awk '$3 ~ /^[bBdD]$/' | tail -n 4 |
    awk '{ size = $2 + 0; $1 = ""; $2 = ""; $3 = ""; printf "  %7d %s\n", size, $0 }' || true

echo
echo "frame security in the nrf52840 image: the symbols of aes, ccm, cipher, ctr and"
echo "config_schema::wire::security (code inlined into their callers is not counted)"
nm -S --size-sort -C -t d "$NRF_ELF" 2>/dev/null | awk '$3 ~ /^[tTrR]$/' |
    awk '{ size = $2 + 0; $1 = ""; $2 = ""; $3 = ""; sub(/^ +/, "") }
        /^<?(<[^ ]+ as )?(aes|ccm|cipher|ctr|crypto_common)::|wire::security::/ {
            n++; total += size; line[n] = sprintf("  %7d %s", size, $0)
        }
        END {
            for (i = (n > 5 ? n - 4 : 1); i <= n; i++) print line[i]
            printf "  %7d bytes in %d symbols\n", total, n
        }' || true

# An llvm-objdump beside the llvm-size (rustup's llvm-tools), or on PATH.
OBJDUMP=""
for c in "$(dirname "$(command -v "$SIZE" || echo "$SIZE")")/llvm-objdump" llvm-objdump; do
    if command -v "$c" >/dev/null; then OBJDUMP="$c"; break; fi
done
if [ -n "$OBJDUMP" ] && command -v python3 >/dev/null; then
    echo
    echo "where the nrf52840's code comes from: each instruction counted at the source line it"
    echo "was compiled from (inlined code where it was written: bench/flash_by_source.py)"
    "$OBJDUMP" -d -l --no-show-raw-insn "$NRF_ELF" | python3 bench/flash_by_source.py "$PWD"
fi

echo
echo "capacities (config-schema/src/limits.rs, node-fw/src/runtime.rs)"
grep -hE '^pub const [A-Z_]+: usize = ' config-schema/src/limits.rs node-fw/src/runtime.rs |
    sed -E 's/^pub const ([A-Z_]+): usize = (.*);/\1=\2/' |
    awk '{ printf "  %-22s", $0; if (NR % 4 == 0) printf "\n" } END { if (NR % 4) printf "\n" }'
