"""Checks the per-platform extension zips that `blender_ext.py build --split-platforms` wrote.

    python scripts/check_zips.py DIST/shapesmith-X.Y.Z.zip PLATFORM...

For each PLATFORM, shapesmith-X.Y.Z-PLATFORM.zip (with "_" for "-") must carry exactly the
wheel scripts/build made for it (dist/wheelhouse/PLATFORM) and a manifest that names that
platform and wheel alone once Blender applies its `[build.generated]` table. The linux-x64 zip
must be what the default `scripts/build` makes (shapesmith-X.Y.Z.zip): the same files, byte for
byte, and the same manifest once generated. Exits 1 naming every failure.
"""

import os
import sys
import tomllib
import zipfile


def manifest(archive):
    """The manifest as Blender reads it from an installed zip: [build.generated] swapped in."""
    data = tomllib.loads(archive.read("blender_manifest.toml").decode("utf-8"))
    generated = data.pop("build", {}).get("generated", {})
    data.update(generated)
    return data


def contents(archive):
    return {name: archive.read(name) for name in archive.namelist() if name != "blender_manifest.toml"}


def main(argv):
    if len(argv) < 2:
        print("usage: check_zips.py DIST/shapesmith-X.Y.Z.zip PLATFORM...", file=sys.stderr)
        return 2
    base, platforms = argv[0], argv[1:]
    wheelhouse = os.path.join(os.path.dirname(base), "wheelhouse")
    failures = []
    for platform in platforms:
        path = f"{base[:-len('.zip')]}-{platform.replace('-', '_')}.zip"
        wheels = [name for name in os.listdir(os.path.join(wheelhouse, platform)) if name.endswith(".whl")]
        if not os.path.isfile(path):
            failures.append(f"{path} was not written")
            continue
        with zipfile.ZipFile(path) as archive:
            carried = sorted(n[len("wheels/"):] for n in archive.namelist() if n.startswith("wheels/") and n.endswith(".whl"))
            if carried != wheels:
                failures.append(f"{os.path.basename(path)} carries {carried}, not {platform}'s {wheels}")
            data = manifest(archive)
            if data.get("platforms") != [platform] or data.get("wheels") != [f"./wheels/{w}" for w in wheels]:
                failures.append(f"{os.path.basename(path)}'s manifest says platforms {data.get('platforms')}, "
                                f"wheels {data.get('wheels')}")
            if platform == "linux-x64":
                with zipfile.ZipFile(base) as default:
                    if contents(archive) != contents(default):
                        failures.append(f"{os.path.basename(path)} differs from {os.path.basename(base)}")
                    if manifest(archive) != manifest(default):
                        failures.append(f"{os.path.basename(path)}'s manifest differs from {os.path.basename(base)}'s")
        if not failures:
            print(f"{os.path.basename(path)}: {', '.join(carried)} (manifest: platforms {data['platforms']})")
    for failure in failures:
        print(f"check_zips: {failure}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
