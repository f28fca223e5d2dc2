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
    """The native module, or NativeUnavailableError saying why it cannot be used. On a
    threaded job's worker (`blender.jobs`), its functions hand Blender's main thread the
    baton for the length of each call."""
    if _native is None:
        raise NativeUnavailableError(STATUS)
    from .blender import jobs

    return _WorkerCalls() if jobs.on_worker() else _native


class _WorkerCalls:
    """The native module seen from a job's worker: each function call inside `jobs.in_native`."""

    def __getattr__(self, name):
        import types

        from .blender import jobs

        attribute = getattr(_native, name)
        if not isinstance(attribute, types.BuiltinFunctionType):
            return attribute

        def call(*args, **kwargs):
            with jobs.in_native():
                return attribute(*args, **kwargs)

        return call


def error_types():
    """Exceptions that mean "the user's data or request is at fault": reported, not raised."""
    return (module().ShapesmithError,)
