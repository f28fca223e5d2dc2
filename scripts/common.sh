# Shared settings for Shapesmith's scripts (sourced, not run).
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${SHAPESMITH_CACHE:-$HOME/.cache/shapesmith}
export SHAPESMITH_CACHE=$CACHE
# Rust builds stay inside the clone: cargo judges a workspace crate fresh by its files' times
# at the paths it last built from, so a target dir shared by two clones can hand one clone a
# library built from the other's sources. The wheel build (zig, manylinux_2_28) has its own
# target dir so the two never rebuild HiGHS over each other.
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$ROOT/target}
WHEEL_TARGET_DIR=$ROOT/target/wheel
export CMAKE_BUILD_PARALLEL_LEVEL=${CMAKE_BUILD_PARALLEL_LEVEL:-2}
# The Blenders the tests run on: the oldest the manifest accepts (4.2 LTS, Python 3.11), the
# current LTS (3.11) and the newest release (3.13).
BPY_OLDEST=4.2.23
BPY_LTS=4.5.15
BPY_NEW=5.2.3
VENV_OLDEST=$CACHE/venv-bpy-$BPY_OLDEST
VENV_LTS=$CACHE/venv-bpy-$BPY_LTS
VENV_NEW=$CACHE/venv-bpy-$BPY_NEW
ANNY_VERSION=0.6.2
EXTENSION_VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' "$ROOT/addon/blender_manifest.toml")
EXTENSION_ZIP=$ROOT/dist/shapesmith-$EXTENSION_VERSION.zip

log() { printf '\033[1m[shapesmith]\033[0m %s\n' "$*" >&2; }
die() { printf 'shapesmith: error: %s\n' "$*" >&2; exit 1; }

# Cross builds (scripts/build --all-platforms, scripts/test-windows) share one target dir of
# their own, one subdirectory per target triple, so the Linux loop never rebuilds for them.
CROSS_TARGET_DIR=$ROOT/target/cross
WINDOWS_TRIPLE=x86_64-pc-windows-gnu

# Windows through Debian's MinGW-w64 (the MSVC target needs Microsoft's SDK). HiGHS is C++ with
# std::thread, so the POSIX-threads g++ builds it. Its build links `-lstdc++`; a link directory
# searched first that holds only the static C++ and winpthread runtimes makes the linker take
# those, so the .pyd needs no MinGW DLL that another add-on could shadow with its own copy.
windows_toolchain() {
  local static=$CROSS_TARGET_DIR/mingw-static
  mkdir -p "$static"
  ln -sf "$(x86_64-w64-mingw32-g++-posix -print-file-name=libstdc++.a)" "$static/libstdc++.a"
  ln -sf "$(x86_64-w64-mingw32-gcc-posix -print-file-name=libwinpthread.a)" "$static/libwinpthread.a"
  ln -sf "$(x86_64-w64-mingw32-gcc-posix -print-file-name=libwinpthread.a)" "$static/libpthread.a"
  export CC_x86_64_pc_windows_gnu=x86_64-w64-mingw32-gcc-posix
  export CXX_x86_64_pc_windows_gnu=x86_64-w64-mingw32-g++-posix
  export AR_x86_64_pc_windows_gnu=x86_64-w64-mingw32-ar
  export CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER=x86_64-w64-mingw32-gcc-posix
  export CARGO_TARGET_X86_64_PC_WINDOWS_GNU_RUSTFLAGS="-L native=$static -C link-arg=-static-libgcc"
}
