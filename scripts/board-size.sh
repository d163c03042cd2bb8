#!/usr/bin/env bash
# Print the board binary's flash and static RAM use. Never fails CI for want of a size tool:
# llvm-size-NN, then llvm-size, then (arm-none-eabi-)size; otherwise it says so and exits 0.
set -uo pipefail
repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
elf=${1:-${CARGO_TARGET_DIR:-$repo_root/target/debian-rustc}/thumbv6m-none-eabi/release/imunoise-board}
if [ ! -f "$elf" ]; then
  elf=$repo_root/target/thumbv6m-none-eabi/release/imunoise-board
fi
tool=""
for t in llvm-size-14 llvm-size arm-none-eabi-size size; do
  if command -v "$t" >/dev/null; then tool=$t; break; fi
done
if [ -z "$tool" ] || [ ! -f "$elf" ]; then
  echo "board-size: no size tool or no ELF ($elf); skipped"
  exit 0
fi
# Section sizes (SysV format: name size address). Flash: everything loaded from flash
# (.boot2, .vector_table, .text, .rodata, and .data's initial values); RAM: .data, .bss, .uninit.
"$tool" -A "$elf" 2>/dev/null | awk '
  $1 ~ /^\.(boot2|vector_table|text|rodata)$/ { flash += $2 }
  $1 == ".data" { flash += $2; ram += $2 }
  $1 ~ /^\.(bss|uninit)$/ { ram += $2 }
  END {
    printf "board flash: %d bytes (%.1f KiB of 2048 KiB; aim < 64 KiB)\n", flash, flash / 1024
    printf "board static RAM: %d bytes (%.1f KiB of 264 KiB; aim < 32 KiB)\n", ram, ram / 1024
  }' || echo "board-size: $tool failed; skipped"
exit 0
