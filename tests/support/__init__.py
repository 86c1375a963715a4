"""Test support: the scene corpus built the way users make files (tests/support/corpus.py).

``corpus`` is a session fixture (imported by tests/conftest.py): the manifest dict of
``corpus.build``, cached under the system temporary folder by the content hash of corpus.py.
"""
import os
import tempfile

import pytest

from . import corpus as _corpus


def corpus_dir():
    return os.path.join(tempfile.gettempdir(), "illumination-lab-corpus", _corpus.corpus_hash())


@pytest.fixture(scope="session")
def corpus():
    """The corpus manifest: {"files": {STEM: {"path", "meshes", "unsupported", "lights", ...}}}."""
    return _corpus.build(corpus_dir())
