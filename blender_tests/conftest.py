"""Headless Blender (the bpy wheel) with the built extension zip installed into an isolated
user directory, and the sample rig built from the MakeHuman assets.

scripts/test sets SHAPESMITH_ZIP and BLENDER_USER_RESOURCES; run alone, the zip defaults to
dist/ and the user directory to a temporary one.
"""

import glob
import hashlib
import os
import subprocess
import sys
import tempfile

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="shapesmith-blender-user-"))

import bpy  # noqa: E402  (after BLENDER_USER_RESOURCES is set)

BATCH = os.path.join(ROOT, "scripts", "batch.py")


def pytest_unconfigure(config):
    """Blender shuts down (its panels, add-ons and windows freed) when Python frees the `bpy`
    module, which it does only once nothing else holds it. typing's caches outlive the module:
    the glTF exporter's `typing.List[Keyframe]` keeps its class, whose module holds `bpy`, so
    on bpy 4.2 Blender's own exit then frees Python-defined panels after Python has ended
    (exit code 139 with every test passed). Emptying the caches lets `bpy` go in its turn."""
    import typing

    for clear in getattr(typing, "_cleanups", ()):  # private; absent, nothing to clear
        clear()


def extension_zip():
    path = os.environ.get("SHAPESMITH_ZIP") or max(glob.glob(os.path.join(ROOT, "dist", "shapesmith-*.zip")), default=None)
    if not path or not os.path.isfile(path):
        pytest.exit("no extension zip: run scripts/build first", returncode=2)
    return path


@pytest.fixture(scope="session")
def shapesmith():
    """The installed, enabled extension package."""
    import addon_utils
    import importlib

    result = bpy.ops.extensions.package_install_files(
        filepath=extension_zip(), repo="user_default", enable_on_install=True, overwrite=True
    )
    assert result == {"FINISHED"}
    names = [m.__name__ for m in addon_utils.modules() if m.__name__.endswith(".shapesmith")]
    assert names, "the extension did not install"
    addon_utils.enable(names[0], default_set=True)
    return importlib.import_module(names[0])


@pytest.fixture(scope="session")
def sample_path(shapesmith):
    """sample.blend for this Blender version and this scripts/makehuman.py (its digest is in
    the name, so a changed sample never reuses an older cached file), built by
    `batch.py sample` when missing. With the extension installed, so that a test running
    batch commands on it passes alone as in the whole suite."""
    sys.path.insert(0, os.path.join(ROOT, "scripts"))
    import batch

    path = batch.cached_sample_path()
    if not os.path.isfile(path):
        run_batch("sample", "--output", path, check=True)
    return path


@pytest.fixture
def sample(sample_path, shapesmith):
    """A fresh copy of the sample file opened in this Blender; returns its path."""
    bpy.ops.wm.open_mainfile(filepath=sample_path)
    return sample_path


def make_active(obj):
    for other in bpy.context.view_layer.objects:
        other.select_set(False)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    return obj


def run_batch(*args, check=False):
    """Runs scripts/batch.py as a pipeline would, in a separate process."""
    proc = subprocess.run([sys.executable, BATCH, "--", *args], capture_output=True, text=True, env=os.environ.copy())
    if check and proc.returncode != 0:
        raise AssertionError(f"batch.py {' '.join(args)} failed ({proc.returncode}):\n{proc.stderr}")
    return proc


def file_digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()
