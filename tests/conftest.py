"""Shared fixtures."""

import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).parent))  # tests/helpers.py


@pytest.fixture(scope="module")
def one_thread():
    """Run a module's small networks on one thread: on a shared 2-core machine two threads can be far slower."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


#: what a test uses -> its marker, for the tests not marked by hand: a test whose function names one of these
#: (a helper it calls, a module it reads) drives a browser or Blender
BROWSER_NAMES = {"headless_chromium", "require_chromium"}
BLENDER_NAMES = {"read_in_blender", "blender_fbx", "write_fbx", "export_fbx", "blender"}


#: modules whose fixtures train models or build corpora (their tests are training tests as a whole)
TRAINING_MODULES = {"test_gesture_training", "test_speech_training", "test_gesture_learns", "test_gesture_eval",
                    "test_corpus", "test_motion_vae", "test_speech_pretrained", "test_perception_hearings"}
#: modules that read Debian's recorded speech or run its speech engines (make test installs them)
APT_MODULES = {"test_real_speech", "test_voices", "test_labelled_speech", "test_timeline"}


def _names(function) -> set[str]:
    code = getattr(function, "__code__", None)
    return set(code.co_names) | set(code.co_varnames) if code is not None else set()


def pytest_collection_modifyitems(items):
    """Mark the browser, Blender and benchmark tests (``make test-fast`` leaves them out, with the training
    tests and those that need Debian's packages: ``-m "not training and not browser and not blender and not bench
    and not apt"``)."""
    for item in items:
        names = _names(getattr(item, "function", None))
        if names & BROWSER_NAMES:
            item.add_marker(pytest.mark.browser)
        if names & BLENDER_NAMES:
            item.add_marker(pytest.mark.blender)
        module = item.module.__name__
        if module == "test_bench":
            item.add_marker(pytest.mark.bench)
        if module in TRAINING_MODULES:
            item.add_marker(pytest.mark.training)
        if module in APT_MODULES:
            item.add_marker(pytest.mark.apt)
