#!/usr/bin/env bash
# Build the firmware image for the emulated board (--features emulator) and put it at
# target/emu/imunoise-board, where tests/emu/ looks for it.
#
# It is built in the board's own target folder (scripts/thumbv6m.sh's), so `core`, built
# from source there, and every dependency but rp2040-hal are the board build's: 12 s instead
# of 100 s from an empty folder. The flashable image's path in that folder is then built
# again without the feature (cargo keeps both, so that takes a second), because an image
# with the compiler's intrinsics and board id 0 must never be what gets flashed.
set -euo pipefail
repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$repo_root"
build=(scripts/thumbv6m.sh build --manifest-path firmware/board/Cargo.toml --release)

restore() { "${build[@]}" --quiet; }
trap restore EXIT
# Cargo prints each artifact as a JSON line; the emulator image's path is the binary's
# "executable".
elf=$("${build[@]}" --features emulator --message-format=json-render-diagnostics |
  sed -n 's/.*"executable":"\([^"]*imunoise-board\)".*/\1/p' | tail -n1)
if [ -z "$elf" ] || [ ! -f "$elf" ]; then
  echo "emulator-image.sh: cargo named no imunoise-board executable" >&2
  exit 1
fi
mkdir -p target/emu
cp "$elf" target/emu/imunoise-board.tmp
mv target/emu/imunoise-board.tmp target/emu/imunoise-board
echo "emulator-image.sh: target/emu/imunoise-board (from $elf)" >&2
