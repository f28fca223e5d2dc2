"""Installs the Shapesmith extension zip into this Blender's user extensions and enables it.

    blender -b -P scripts/install_extension.py -- dist/shapesmith-X.Y.Z.zip
    python scripts/install_extension.py -- dist/shapesmith-X.Y.Z.zip     (bpy wheel)

Set BLENDER_USER_RESOURCES first to install into an isolated user directory (the tests and
the demo do), so a rigger's own Blender setup is never touched.
"""

import os
import sys

import bpy


def main():
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    if len(args) != 1 or not os.path.isfile(args[0]):
        print(f"shapesmith: error: give the extension zip to install, got {args}", file=sys.stderr)
        return 2
    result = bpy.ops.extensions.package_install_files(
        filepath=os.path.abspath(args[0]), repo="user_default", enable_on_install=True, overwrite=True
    )
    if result != {"FINISHED"}:
        print(f"shapesmith: error: installing {args[0]} returned {result}", file=sys.stderr)
        return 1
    bpy.ops.wm.save_userpref()
    import shapesmith_native

    print(f"installed {os.path.basename(args[0])} (native core {shapesmith_native.__version__}) "
          f"into {bpy.utils.user_resource('EXTENSIONS')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
