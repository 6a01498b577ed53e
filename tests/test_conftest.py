"""The session setup of the root ``conftest.py``: a test session leaves nothing in the system's temporary
folder (TorchInductor's cache, pytest's ``tmp_path`` folders, the xdist workers' files)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow  # a pytest session in a subprocess
def test_a_session_leaves_the_temporary_folder_as_it_was(tmp_path) -> None:
    system_tmp = tmp_path / "system_tmp"
    system_tmp.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "TORCHINDUCTOR_CACHE_DIR"}
    env.update(TMPDIR=str(system_tmp), OMP_NUM_THREADS="1")
    selection = [
        "tests/filters/test_soft_clip.py::TestSoftClip::test_compile",  # TorchInductor's compile cache
        "tests/core/test_files.py",  # pytest's tmp_path folders
    ]
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "-p", "no:cacheprovider", *selection],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    assert sorted(os.listdir(system_tmp)) == []
