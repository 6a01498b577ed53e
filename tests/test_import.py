"""``import kornia_ilum`` stays cheap: no Dynamo, no heavy optional modules, no files written anywhere."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _run(code_or_args: list[str], tmp_path: Path) -> subprocess.CompletedProcess[str]:
    """Run Python in a fresh process whose TMPDIR and CWD are empty folders of ``tmp_path``."""
    tmp, cwd = tmp_path / "tmp", tmp_path / "cwd"
    tmp.mkdir(exist_ok=True)
    cwd.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k not in ("TORCHINDUCTOR_CACHE_DIR", "TRITON_CACHE_DIR")}
    env.update(TMPDIR=str(tmp), TEMP=str(tmp), TMP=str(tmp))
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PYTHONDONTWRITEBYTECODE"] = "1"  # the check is about what kornia_ilum writes, not Python's caches
    return subprocess.run([sys.executable, *code_or_args], capture_output=True, text=True, env=env, cwd=cwd,
                          timeout=300, check=False)


def _assert_nothing_written(tmp_path: Path) -> None:
    assert sorted(os.listdir(tmp_path / "tmp")) == [], "TMPDIR"
    assert sorted(os.listdir(tmp_path / "cwd")) == [], "CWD"


def _heavy_loaded(setup: str, heavy: tuple[str, ...], tmp_path: Path) -> str:
    """Run ``setup`` in a fresh process (:func:`_run`); return the modules of ``heavy`` it loaded, joined
    by commas (``""``: none)."""
    probe = f"import sys\n{setup}\nprint(','.join(m for m in {heavy!r} if m in sys.modules))\n"
    result = _run(["-c", probe], tmp_path)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


@pytest.mark.slow  # a subprocess
def test_import_writes_nothing_and_loads_no_dynamo(tmp_path):
    heavy = ("torch._dynamo", "torch._inductor", "sympy", "scipy", "matplotlib", "mitsuba", "cv2",
             "OpenImageIO", "safetensors", "skimage", "onnxruntime", "onnx", "onnxscript")
    loaded = _heavy_loaded("import kornia_ilum", heavy, tmp_path)
    assert loaded == "", f"import kornia_ilum loaded {loaded}"
    _assert_nothing_written(tmp_path)


@pytest.mark.slow  # a subprocess
def test_cli_list_writes_nothing(tmp_path):
    result = _run(["-m", "kornia_ilum", "list"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert "ours" in result.stdout
    _assert_nothing_written(tmp_path)


@pytest.mark.slow  # a subprocess
def test_cli_import_stays_light(tmp_path):
    """``kornia-ilum --help``, ``list`` and ``estimate`` start without what only other sub-commands need
    (Mitsuba, matplotlib, the light stage, the environments' statistics): ``train`` and ``evaluate``, whose
    packages load the light stage, get their real parser only when the command line names them."""
    heavy = ("torch._dynamo", "matplotlib", "mitsuba", "onnxruntime", "OpenImageIO",
             "kornia_ilum_lab.synth", "kornia_ilum_lab.train", "kornia_ilum_lab.evaluation")
    setup = "import kornia_ilum.cli\nkornia_ilum.cli.build_parser('estimate')"
    loaded = _heavy_loaded(setup, heavy, tmp_path)
    assert loaded == "", f"import kornia_ilum.cli loaded {loaded}"
    _assert_nothing_written(tmp_path)
