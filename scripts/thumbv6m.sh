#!/usr/bin/env bash
# Run cargo for thumbv6m-none-eabi (the RP2040's Cortex-M0+), on any machine with rustup.
#
#   scripts/thumbv6m.sh build -p protocol --release
#   scripts/thumbv6m.sh clippy -p protocol -- -D warnings
#
# If rustup already has the thumbv6m-none-eabi target installed, this is plain
# `cargo <args> --target thumbv6m-none-eabi`. It never downloads a rustup target.
# Otherwise (this project's machines and CI, where rustup targets cannot be fetched) it uses
# Debian's rustc-web compiler and its rust-web-src library sources, same version, extracted
# with `dpkg -x` into a cache folder — not installed, so rustup's toolchain stays first on PATH
# — and builds `core` from source with -Zbuild-std. See docs/ARCHITECTURE.md, "Toolchain and memory map".
#
# Environment:
#   IMUNOISE_TOOLCHAIN_CACHE  cache folder (default: ~/.cache/imunoise/toolchain)
#   CARGO_TARGET_DIR          honoured; by default the Debian build uses target/debian-rustc
#                             so its artifacts never mix with rustup's.
set -euo pipefail

target=thumbv6m-none-eabi
repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

if [ $# -eq 0 ]; then
  echo "usage: $0 <cargo subcommand> [args...]   (e.g. build -p protocol --release)" >&2
  exit 2
fi
subcommand=$1
shift

# The board's defmt log level. firmware/board/.cargo/config.toml sets it too, but cargo reads
# config from the working directory, not from --manifest-path, so builds from the repository
# root would otherwise get defmt's default (errors only) and an emulated board would log
# nothing.
export DEFMT_LOG="${DEFMT_LOG:-info}"

# Split the caller's args at `--` so that --target goes before arguments meant for the tool.
cargo_args=()
tool_args=()
seen_separator=0
for arg in "$@"; do
  if [ "$seen_separator" = 1 ]; then tool_args+=("$arg");
  elif [ "$arg" = "--" ]; then seen_separator=1;
  else cargo_args+=("$arg"); fi
done
run_cargo() {
  if [ ${#tool_args[@]} -gt 0 ]; then
    "$@" "${cargo_args[@]}" --target "$target" -- "${tool_args[@]}"
  else
    "$@" "${cargo_args[@]}" --target "$target"
  fi
}

if command -v rustup >/dev/null && rustup target list --installed 2>/dev/null | grep -qx "$target"; then
  echo "thumbv6m.sh: using rustup's installed $target target" >&2
  cd "$repo_root"
  run_cargo cargo "$subcommand"
  exit $?
fi

# ---- Debian rustc-web fallback -------------------------------------------------------------
cache=${IMUNOISE_TOOLCHAIN_CACHE:-$HOME/.cache/imunoise/toolchain}

apt_candidate() { apt-cache policy "$1" 2>/dev/null | awk '/Candidate:/ {print $2}'; }

version=$(apt_candidate rustc-web)
if [ -z "$version" ] || [ "$version" = "(none)" ]; then
  # Package lists may be missing on a fresh machine: refresh them once (needs root).
  apt-get update -qq >&2 || true
  version=$(apt_candidate rustc-web)
fi
if [ -z "$version" ] || [ "$version" = "(none)" ]; then
  echo "thumbv6m.sh: no $target target in rustup and no Debian rustc-web package available" >&2
  exit 1
fi
upstream=${version%%+*}            # 1.96.0+dfsg1-1~deb12u2 -> 1.96.0
major_minor=${upstream%.*}         # -> 1.96
dir="$cache/rustc-web-$version"

if [ ! -x "$dir/usr/bin/rustc" ] || [ ! -f "$dir/.complete" ]; then
  echo "thumbv6m.sh: fetching Debian rustc-web $version into $dir" >&2
  rm -rf "$dir"
  mkdir -p "$dir/debs"
  libstd="libstd-rust-web-$major_minor"
  # libstd links against one libllvmNN; lld-NN of the same NN provides the linker.
  llvm_pkg=$(apt-cache show "$libstd=$version" | awk -F': ' '/^Depends:/ {print $2; exit}' \
    | tr ',' '\n' | grep -o 'libllvm[0-9]\+' | head -n1)
  llvm_major=${llvm_pkg#libllvm}
  if [ -z "$llvm_major" ]; then
    echo "thumbv6m.sh: cannot tell which libllvm $libstd $version needs" >&2
    exit 1
  fi
  (
    cd "$dir/debs"
    apt-get download -qq "rustc-web=$version" "rust-web-src=$version" "rust-web-clippy=$version" \
      "$libstd=$version" "libstd-rust-web-dev=$version" "$llvm_pkg" "lld-$llvm_major" >&2
    for deb in ./*.deb; do dpkg -x "$deb" "$dir"; done
  )
  rm -rf "$dir/debs"
  echo "$llvm_major" >"$dir/.llvm-major"
  touch "$dir/.complete"
fi

llvm_major=$(cat "$dir/.llvm-major")
# rustc looks for `rust-lld` on PATH for thumbv6m-none-eabi; Debian ships it as plain lld.
mkdir -p "$dir/bin"
ln -sf "$dir/usr/lib/llvm-$llvm_major/bin/lld" "$dir/bin/rust-lld"

export RUSTC="$dir/usr/bin/rustc"
export LD_LIBRARY_PATH="$dir/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PATH="$dir/bin:$PATH"
export RUSTC_BOOTSTRAP=1
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$repo_root/target/debian-rustc}
if [ "$subcommand" = "clippy" ]; then
  # rustup's clippy-driver cannot lint with another compiler; Debian's clippy (same version) can.
  # cargo-clippy passes the lint arguments to clippy-driver in CLIPPY_ARGS, each followed
  # by __CLIPPY_HACKERY__; plain `cargo check` with the wrapper needs them the same way.
  export RUSTC_WORKSPACE_WRAPPER="$dir/usr/bin/clippy-driver"
  clippy_args=""
  for arg in ${tool_args[@]+"${tool_args[@]}"}; do clippy_args+="${arg}__CLIPPY_HACKERY__"; done
  export CLIPPY_ARGS="$clippy_args"
  tool_args=()
  subcommand=check
fi
echo "thumbv6m.sh: using Debian rustc-web $version with -Zbuild-std=core" >&2
cd "$repo_root"
run_cargo cargo "$subcommand" -Zbuild-std=core
