"""The wheels: ``python -m build`` makes one for the library, one for the lab and one for each plugin, with their
weights and licences inside; installed into a clean virtual environment (the package index and the pinned CPU
torch of ``constraints.txt``, nothing else) without the lab, ``kornia-ilum list`` and ``kornia-ilum estimate`` run
and the lab's commands say how to install it; with the lab, they run."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Each package: its source folder, its import name, and the files its wheel must hold besides the code.
PACKAGES = {
    "kornia_ilum": (ROOT, "kornia_ilum", ["kornia_ilum/estimators/weights/ours.safetensors",
                                          "kornia_ilum/estimators/weights/probe.safetensors",
                                          "kornia_ilum/estimators/weights/probe.jpg",
                                          "kornia_ilum/estimators/weights/MODEL_CARD.md",
                                          "kornia_ilum/detection/weights/yunet.safetensors",
                                          "kornia_ilum/detection/weights/LICENSE-yunet.txt"]),
    "kornia_ilum_sh": (ROOT / "plugins/sh", "kornia_ilum_sh", ["kornia_ilum_sh/weights/sh.safetensors",
                                                                "kornia_ilum_sh/weights/MODEL_CARD.md"]),
    "kornia_ilum_sipr": (ROOT / "plugins/sipr", "kornia_ilum_sipr", ["kornia_ilum_sipr/weights/sipr.safetensors",
                                                                      "kornia_ilum_sipr/weights/MODEL_CARD.md"]),
    "kornia_ilum_uniform": (ROOT / "plugins/uniform", "kornia_ilum_uniform", []),
    "kornia_ilum_lab": (ROOT / "plugins/lab", "kornia_ilum_lab", []),
}


def _source_copy(source: Path, package: str, target: Path) -> Path:
    """The files a build reads, copied, so that the build writes its ``build/`` and ``.egg-info`` there and not
    into the checkout."""
    target.mkdir(parents=True)
    for name in ("pyproject.toml", "README.md", "LICENSE", "ASSETS.md"):
        if (source / name).is_file():
            shutil.copy2(source / name, target / name)
    shutil.copytree(source / package, target / package, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    return target


def _run(args: list[str], cwd: Path, timeout: int = 900) -> subprocess.CompletedProcess:
    result = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout, check=False,
                            env={**os.environ, "PYTHONNOUSERSITE": "1"})
    assert result.returncode == 0, f"{' '.join(args)}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result


@pytest.mark.slow
def test_wheels_build_install_and_run_in_a_clean_venv(tmp_path) -> None:
    dist = tmp_path / "dist"
    for name, (source, package, extra) in PACKAGES.items():
        copy = _source_copy(source, package, tmp_path / "src" / name)
        _run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(dist), str(copy)], tmp_path)
        wheel = next(dist.glob(f"{name}-*.whl"))
        with zipfile.ZipFile(wheel) as zf:
            names = set(zf.namelist())
        missing = [f for f in extra if f not in names]
        assert not missing, f"{wheel.name} lacks {missing}"
        licences = {n.rsplit("/", 1)[-1] for n in names if ".dist-info/licenses/" in n}
        assert "LICENSE" in licences and (name != "kornia_ilum" or "ASSETS.md" in licences), sorted(licences)
        if name != "kornia_ilum_lab":  # the library and the estimator plugins hold none of the lab's modules
            assert not any(n.startswith("kornia_ilum_lab/") or "/synth/" in n or "/train/" in n for n in names)
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], tmp_path)
    python, cli = venv / "bin" / "python", venv / "bin" / "kornia-ilum"
    wheels = sorted(str(p) for p in dist.glob("*.whl") if not p.name.startswith("kornia_ilum_lab-"))
    _run([str(python), "-m", "pip", "install", "-q", "-c", str(ROOT / "constraints.txt"), *wheels], tmp_path)
    # the library without the lab: it estimates, and names the lab's commands with the line that installs it
    assert "kornia_ilum_lab" not in _run([str(python), "-m", "pip", "list"], tmp_path).stdout
    assert "needs the lab" in _run([str(cli), "--help"], tmp_path).stdout
    missing = subprocess.run([str(cli), "train", "--help"], capture_output=True, text=True, timeout=300, check=False)
    assert missing.returncode == 2 and "-e ./plugins/lab" in missing.stderr
    probe = _run([str(python), "-c", "import torch, kornia_ilum, kornia_ilum_sipr; "
                  "print(torch.__version__, torch.version.cuda, kornia_ilum.__file__)"], tmp_path).stdout
    version, cuda, where = probe.split()
    assert version.startswith("2.13.0") and cuda == "None" and str(venv) in where  # the CPU torch, the wheel
    listing = _run([str(cli), "list"], tmp_path).stdout
    assert all(name in listing for name in ("ours", "sh", "sipr", "uniform"))
    out = tmp_path / "out"
    _run([str(cli), "estimate", "-o", f"{out}/"], tmp_path)
    assert sorted(p.name for p in out.iterdir()) == ["astronaut.exr", "astronaut.json"]
    # then the lab: its commands join kornia-ilum
    lab = next(str(p) for p in dist.glob("kornia_ilum_lab-*.whl"))
    _run([str(python), "-m", "pip", "install", "-q", "-c", str(ROOT / "constraints.txt"), lab], tmp_path)
    assert "--checkpoint-every" in _run([str(cli), "train", "--help"], tmp_path).stdout
