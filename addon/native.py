"""The only importer of `shapesmith_native` (the Rust core bundled as a wheel).

A missing or broken wheel must not stop the add-on from loading: panels show `STATUS` and
operators raise a clear error through `module()`. The message names this machine's platform
and the platforms this copy of the extension was built for, since the usual cause is the zip
for another platform (each platform has its own zip, see docs/platforms.md).
"""

import os
import platform

# How Blender names platforms in an extension manifest (blender_ext.py, platform_from_this_system).
_SYSTEMS = {"darwin": "macos"}
_MACHINES = {"x86_64": "x64", "amd64": "x64", "aarch64": "arm64", "aarch32": "arm32"}


def this_platform():
    """This machine as Blender names it in a manifest's `platforms` (e.g. "windows-x64")."""
    system = platform.system().lower()
    machine = platform.machine().lower()
    return f"{_SYSTEMS.get(system, system)}-{_MACHINES.get(machine, machine)}"


def built_platforms():
    """The platforms this copy of the extension was built for, from its manifest.

    A zip built with `--split-platforms` keeps the source's full list under `platforms` and
    names its own one under `[build.generated]`, which Blender reads first.
    """
    import tomllib

    try:
        with open(os.path.join(os.path.dirname(__file__), "blender_manifest.toml"), "rb") as manifest_file:
            manifest = tomllib.load(manifest_file)
    except (OSError, tomllib.TOMLDecodeError):
        return []
    generated = manifest.get("build", {}).get("generated", {})
    return list(generated.get("platforms", manifest.get("platforms", [])))


def unavailable_status(error, found, built):
    """What the panels and operators say when the wheel cannot be imported."""
    built_text = ", ".join(built) if built else "no platform"
    if found in built:
        advice = "reinstall the Shapesmith extension"
    else:
        advice = f"install the Shapesmith zip for {found}"
    return f"native core unavailable on {found}, this Shapesmith was built for {built_text} ({advice}): {error}"


try:
    import shapesmith_native as _native
except ImportError as error:  # the wheel is missing or built for another platform
    _native = None
    STATUS = unavailable_status(error, this_platform(), built_platforms())
else:
    STATUS = f"native core {_native.__version__}"


class NativeUnavailableError(RuntimeError):
    pass


def module():
    """The native module, or NativeUnavailableError saying why it cannot be used."""
    if _native is None:
        raise NativeUnavailableError(STATUS)
    return _native


def error_types():
    """Exceptions that mean "the user's data or request is at fault": reported, not raised."""
    return (module().ShapesmithError,)
