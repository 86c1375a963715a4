"""Fixtures: bpy tests start from factory settings with the add-on registered once per session.

tests/core imports no bpy; these fixtures import it lazily so that tests/core
runs in an environment without it.
"""
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from tests.support import corpus  # noqa: E402,F401  (session fixture: the scene corpus)


def _needs_bpy(request):
    return "core" not in request.node.path.relative_to(ROOT).parts[1:2]


@pytest.fixture(scope="session")
def addon_registered():
    """Register the add-on (as a plain package named ``addon``) for the whole session."""
    import addon
    addon.register()
    yield addon
    addon.unregister()


@pytest.fixture(autouse=True)
def factory_reset(request):
    """Every bpy test starts from an empty factory file with the add-on registered."""
    if not _needs_bpy(request):
        yield
        return
    import bpy
    request.getfixturevalue("addon_registered")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield


def run_script(name, *args, timeout=600, env=None):
    """Run ``scripts/<name>`` as a pipeline would: a subprocess of this Python (the bpy module)."""
    full_env = dict(os.environ, **(env or {}))
    return subprocess.run([sys.executable, os.path.join(ROOT, "scripts", name), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, env=full_env, cwd=ROOT)


@pytest.fixture
def script():
    return run_script
