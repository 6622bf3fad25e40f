#!/usr/bin/env bash
# Runs the QEMU board image on mps2-an386 until it exits by itself (after its
# sample quota) or the timeout hits. UART0 goes to a file (default
# target/qemu-uart0.capture); decode it with the host tools, or let the smoke
# test do everything: `cargo test -p robimu-tests --test qemu_smoke -- --ignored`
# from the repository root.
#
#   firmware/boards/qemu-mps2/run.sh [ELF] [CAPTURE]
set -euo pipefail
boards="$(cd "$(dirname "$0")/.." && pwd)"
elf="${1:-$boards/target/thumbv7em-none-eabihf/release/robimu-qemu-mps2}"
capture="${2:-$boards/target/qemu-uart0.capture}"
if [ ! -f "$elf" ]; then
    (cd "$boards" && cargo build --release -p robimu-qemu-mps2)
fi
# -icount: guest time advances 2^6 ns per instruction, so the run is
# deterministic whatever the host load (keep in sync with tests/tests/qemu_smoke.rs).
exec timeout --kill-after=5 180 qemu-system-arm \
    -M mps2-an386 -display none -monitor none \
    -icount shift=6,sleep=off \
    -semihosting-config enable=on,target=native \
    -serial "file:$capture" \
    -kernel "$elf"
