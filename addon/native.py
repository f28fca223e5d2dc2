"""The only importer of `shapesmith_native` (the Rust core bundled as a wheel).

A missing or broken wheel must not stop the add-on from loading: panels show `STATUS` and
operators raise a clear error through `module()`.
"""

try:
    import shapesmith_native as _native
except ImportError as error:  # the wheel is missing or built for another platform
    _native = None
    STATUS = f"native core unavailable: {error}"
else:
    STATUS = f"native core {_native.__version__}"


class NativeUnavailableError(RuntimeError):
    pass


def module():
    """The native module, or NativeUnavailableError saying why it cannot be used."""
    if _native is None:
        raise NativeUnavailableError(STATUS + " (reinstall the Shapesmith extension for this platform)")
    return _native


def error_types():
    """Exceptions that mean "the user's data or request is at fault": reported, not raised."""
    return (module().ShapesmithError,)
