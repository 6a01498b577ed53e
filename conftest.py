"""Session-wide test setup for the tests and the doctests: every temporary file goes into one folder of the
test session, removed when the session ends, so the suite leaves nothing in the system's temporary folder.

What would otherwise stay behind: TorchInductor's compile cache (``torchinductor_<user>``), torchrun's
``torchelastic_*`` folders, multiprocessing's ``pymp-*`` folders, and pytest's own ``pytest-of-<user>``.
Setting ``KORNIA_ILUM_KEEP_TEST_TMP=1`` keeps the folder (its path is printed) to look at a failure.

With pytest-xdist the controller makes the folder before it starts the workers, which inherit it through
``TMPDIR`` (and make their own inside it).
"""

from __future__ import annotations

import os
import shutil
import tempfile

import pytest

_session = pytest.MonkeyPatch()  # undone when the session ends
_session_dir: str | None = None


def pytest_configure(config) -> None:
    global _session_dir
    _session_dir = tempfile.mkdtemp(prefix="kornia_ilum_tests_")
    _session.setenv("TMPDIR", _session_dir)  # subprocesses (torchrun, the CLI tests) and their children
    _session.setenv("TORCHINDUCTOR_CACHE_DIR", os.path.join(_session_dir, "torchinductor"))
    _session.setattr(tempfile, "tempdir", _session_dir)  # this process: tempfile, multiprocessing, tmp_path


def pytest_unconfigure(config) -> None:
    _session.undo()
    if _session_dir is None:
        return
    if os.environ.get("KORNIA_ILUM_KEEP_TEST_TMP"):
        print(f"\nkornia_ilum: the test session's temporary folder is kept: {_session_dir}")
    else:
        shutil.rmtree(_session_dir, ignore_errors=True)
