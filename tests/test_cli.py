"""Tests of the ``kornia-ilum`` command line: estimate (outputs, naming), list, and one-line errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import skimage.data
import torch

from kornia_ilum.api import estimate_lighting
from kornia_ilum import cli as cli_module
from kornia_ilum.cli import LAB_COMMANDS, LAZY_COMMANDS, build_parser, main
from kornia_ilum.io import read_hdr, read_ldr, write_ldr

REPO = Path(__file__).resolve().parents[1]


def _png(path: Path, array: np.ndarray) -> str:
    write_ldr(path, torch.from_numpy(array).permute(2, 0, 1).float() / 255)
    return str(path)


@pytest.fixture(scope="module")
def astronaut() -> np.ndarray:
    return skimage.data.astronaut()


@pytest.fixture
def group(astronaut, tmp_path) -> str:
    """A PNG with the astronaut's face pasted three times."""
    canvas = np.full((300, 700, 3), 128, np.uint8)
    for x, y in ((20, 40), (270, 120), (520, 60)):
        canvas[y : y + 160, x : x + 150] = astronaut[40:200, 150:300]
    return _png(tmp_path / "group.png", canvas)


def _error_line(capsys) -> str:
    """The run's stderr, which must be one ``kornia-ilum: error: ...`` line and no traceback."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("kornia-ilum: error: "), err
    assert "Traceback" not in err
    return lines[0]


class TestEstimate:
    def test_sample(self, tmp_path, capsys, astronaut):
        exr, png = tmp_path / "astronaut.exr", tmp_path / "astronaut.png"
        assert main(["estimate", "-o", str(exr), "--preview", str(png), "--preview-size", "32"]) == 0
        out = capsys.readouterr().out
        assert f"wrote {exr} (mirror ball 32x32, face 0 of astronaut" in out
        assert f"wrote {png} (preview 96x32" in out
        assert "astronaut: 1 face (detector yunet, " in out and " ms" in out
        light = estimate_lighting(astronaut)
        torch.testing.assert_close(read_hdr(exr), light.mirror_ball[0])
        assert read_ldr(png).shape == (3, 32, 96)
        assert f"and {exr.stem}.json (main light and ambient SH)" in out
        record = json.loads(exr.with_suffix(".json").read_text())  # the main light beside the .exr
        assert record["image"] == "astronaut" and record["face"] == 0 and len(record["box"]) == 4
        expected = light.dominant_light().to_dict(0)
        assert record.keys() == {"image", "face", "box", "estimator", "log_energy_spread", "scene_share",
                                 "strength_evidence"} | expected.keys()
        assert record["log_energy_spread"] == pytest.approx(float(light.log_energy_spread[0]))
        assert record["scene_share"] is None and record["strength_evidence"] == "face"  # no scene branch
        for key in ("direction", "irradiance_rgb", "ambient_sh_arcore"):
            np.testing.assert_allclose(record[key], expected[key], rtol=1e-5, atol=1e-7)

    def test_default_output(self, tmp_path, monkeypatch, capsys):
        monkeypatch.chdir(tmp_path)
        assert main(["estimate"]) == 0
        assert (tmp_path / "astronaut.exr").is_file()
        assert "wrote astronaut.exr" in capsys.readouterr().out

    def test_latlong_hdr(self, tmp_path):
        assert main(["estimate", "-o", str(tmp_path / "light.hdr"), "--latlong", "16"]) == 0
        assert read_hdr(tmp_path / "light.hdr").shape == (3, 16, 32)
        assert main(["estimate", "-o", str(tmp_path / "light"), "--format", "hdr"]) == 0
        assert read_hdr(tmp_path / "light.hdr").shape == (3, 32, 32)
        assert main(["estimate", "-o", str(tmp_path / "half.exr"), "--half"]) == 0
        assert read_hdr(tmp_path / "half.exr").shape == (3, 32, 32)

    def test_several_images_and_faces(self, tmp_path, astronaut, group, capsys):
        single = _png(tmp_path / "astro.png", astronaut)
        out = tmp_path / "out"
        assert main(["estimate", single, group, "-o", f"{out}/", "--faces", "all"]) == 0
        names = sorted(p.name for p in out.iterdir())
        stems = ["astro_face0", "group_face0", "group_face1", "group_face2"]
        assert names == sorted([f"{s}.exr" for s in stems] + [f"{s}.json" for s in stems])
        assert "group: 3 faces" in capsys.readouterr().out
        pattern = str(tmp_path / "p" / "{stem}-{face}.exr")  # missing folders are created
        assert main(["estimate", group, "-o", pattern, "--faces", "all"]) == 0
        written = sorted(p.name for p in (tmp_path / "p").iterdir() if p.suffix == ".exr")
        assert written == ["group-0.exr", "group-1.exr", "group-2.exr"]
        assert main(["estimate", single, group, "-o", str(tmp_path / "{stem}.exr")]) == 0  # largest face each
        assert (tmp_path / "astro.exr").is_file() and (tmp_path / "group.exr").is_file()

    def test_scene_one_strength_per_photo(self, tmp_path, group, capsys):
        """``--scene FILE``: the faces of a photo share one strength, the JSON says how much the photo set."""
        import safetensors.torch

        from kornia_ilum.estimators import SceneStrength

        torch.manual_seed(0)
        weights = tmp_path / "scene.safetensors"
        safetensors.torch.save_file(SceneStrength().state_dict(), str(weights))
        out = tmp_path / "out"
        assert main(["estimate", group, "-o", f"{out}/", "--faces", "all", "--scene", str(weights)]) == 0
        records = [json.loads(p.read_text()) for p in sorted(out.glob("*.json"))]
        assert len(records) == 3
        shares = [r["scene_share"] for r in records]
        assert all(0.0 < v < 1.0 for v in shares) and len({round(v, 6) for v in shares}) == 1
        assert all(r["strength_evidence"] in ("face", "both", "scene") for r in records)
        spreads = [r["log_energy_spread"] for r in records]
        assert max(spreads) == pytest.approx(min(spreads))  # one strength, one spread
        safetensors.torch.save_file({"w": torch.ones(2)}, str(tmp_path / "bad.safetensors"))
        assert main(["estimate", group, "-o", f"{tmp_path}/bad/", "--scene", str(tmp_path / "bad.safetensors")]) == 1
        assert "holds no scene branch's weights" in capsys.readouterr().err
        assert not (tmp_path / "bad").exists()

    def test_fallback(self, tmp_path, capsys):
        flat = _png(tmp_path / "flat.png", np.full((64, 96, 3), 100, np.uint8))
        assert main(["estimate", flat, "-o", str(tmp_path / "flat.exr"), "--detector", "opencv"]) == 1
        line = _error_line(capsys)
        assert "no face found in image" in line and "--fallback full_image" in line and "--detector yunet" in line
        assert main(["estimate", flat, "-o", str(tmp_path / "flat.exr")]) == 1  # the default: yunet
        line = _error_line(capsys)
        assert "by detector 'yunet'" in line and "--fallback full_image" in line and "--detector yunet" not in line
        assert "fallback='full_image'" not in line  # options, not the API's Python arguments
        assert main(["estimate", flat, "-o", str(tmp_path / "flat.exr"), "--fallback", "full_image"]) == 0
        assert "box [16, 0, 80, 64]" in capsys.readouterr().out

    def test_tta(self, tmp_path, capsys, astronaut):
        exr = tmp_path / "tta.exr"
        assert main(["estimate", "-o", str(exr), "--tta", "2"]) == 0
        assert "estimator ours, runtime eager, tta 2)" in capsys.readouterr().out
        torch.testing.assert_close(read_hdr(exr), estimate_lighting(astronaut, tta=2).mirror_ball[0])

    def test_runtime_detect_side_and_the_stages_of_the_timing_line(self, tmp_path, capsys, astronaut):
        exr, png = tmp_path / "fast.exr", tmp_path / "fast.png"
        argv = ["estimate", "-o", str(exr), "--preview", str(png), "--runtime", "onnx", "--detect-side", "256"]
        assert main(argv) == 0
        out = capsys.readouterr().out
        assert "(runtime onnx)" in out and exr.is_file() and png.is_file()
        line = next(x for x in out.splitlines() if x.startswith("astronaut: 1 face"))
        for stage in ("read", "check", "detect", "crop", "estimate", "write", "preview", "total"):
            assert f"{stage} " in line, stage
        ref = estimate_lighting(astronaut).mirror_ball[0]
        assert float((torch.log1p(read_hdr(exr)) - torch.log1p(ref)).abs().amax()) < 0.05  # boxes differ a little
        assert main(["estimate", "--runtime", "tensorrt"]) == 2

    def test_tta_usage(self, capsys):
        assert main(["estimate", "--tta", "0"]) == 2
        assert "argument --tta: must be a positive integer" in _error_line(capsys)
        assert main(["estimate", "--help"]) == 0
        assert "--tta N" in capsys.readouterr().out


class TestList:
    def test_list(self, capsys):
        assert main(["list"]) == 0
        out = capsys.readouterr().out
        for word in ("uniform", "ours", "opencv", "yunet", "none", "paper:", "input: 256x256", "no weights"):
            assert word in out, word
        assert out.index("Estimators") < out.index("Detectors")


class TestErrors:
    def test_missing_path(self, capsys, tmp_path):
        assert main(["estimate", str(tmp_path / "nope.jpg")]) == 1
        assert _error_line(capsys) == f"kornia-ilum: error: cannot read {tmp_path / 'nope.jpg'}: no such file"
        assert not list(tmp_path.iterdir())

    def test_unreadable(self, capsys, tmp_path):
        (tmp_path / "bad.png").write_text("not an image")
        assert main(["estimate", str(tmp_path / "bad.png"), "-o", str(tmp_path / "x.exr")]) == 1
        captured = capsys.readouterr()
        assert "cannot read" in captured.err and "loaded estimator" not in captured.out  # before the models load

    def test_no_weights(self, capsys, tmp_path, untrained_name):
        assert main(["estimate", "--estimator", untrained_name, "-o", str(tmp_path / "x.exr")]) == 1
        assert "'untrained' is registered but ships no trained weights yet" in _error_line(capsys)

    @pytest.mark.parametrize(
        "argv, message",
        [
            (["estimate", "--faces", "many"], "argument --faces: invalid choice: 'many'"),
            (["estimate", "--latlong", "0"], "argument --latlong: must be a positive integer"),
            (["estimate", "--format", "png"], "argument --format: invalid choice"),
            (["estimate", "-o", "x.png"], "-o must end in .exr or .hdr"),
            (["estimate", "-o", "x.exr", "--format", "hdr"], "does not match --format hdr"),
            (["estimate", "-o", "{name}.exr"], "unknown placeholder(s) name"),
            (["estimate", "--preview", "p.jpg"], "--preview must end in .png"),
            (["estimate", "--estimator", "nope"], "unknown estimator 'nope'; choose one of: "),
            (["estimate", "--detector", "haar"], "unknown detector 'haar'; choose one of: none, opencv, yunet"),
            (["estimate", "-o", "x.hdr", "--half"], "--half applies to .exr files only"),
            (["estimate", "a.png", "b.png", "-o", "x.exr"], "with several images, -o must be a directory or contain {stem}"),
            (["estimate", "a/x.png", "b/x.png", "-o", "out/"], "several images are named 'x'"),
            (["nothing"], "argument COMMAND: invalid choice: 'nothing'"),
            ([], "the following arguments are required: COMMAND"),
        ],
    )
    def test_usage(self, capsys, argv, message):
        assert main(argv) == 2
        assert message in _error_line(capsys)

    def test_help(self, capsys):
        assert main(["estimate", "--help"]) == 0
        out = capsys.readouterr().out
        assert "{stem}" in out and "{face}" in out and "--latlong H" in out

    def test_lazy_commands_show_their_real_help_line(self, capsys):
        """A command line that does not name ``train``/``evaluate`` gets a placeholder parser for each: its
        help line is the real parser's, and naming the command builds the real one."""
        def help_lines(parser):
            sub = next(a for a in parser._actions if a.dest == "command")
            return {c.dest: c.help for c in sub._choices_actions}

        full, light = help_lines(build_parser()), help_lines(build_parser(""))
        assert light == full and set(LAZY_COMMANDS) | set(LAB_COMMANDS) <= set(full)
        assert main(["train", "--help"]) == 0 and "--checkpoint-every" in capsys.readouterr().out

    def test_the_labs_commands_come_from_its_entry_points(self):
        """The lab adds synth, train, evaluate and ablate through the ``kornia_ilum.commands`` entry points, with the
        help lines that ``--help`` shows without the lab."""
        found = cli_module.plugin_commands()
        assert set(LAB_COMMANDS) <= set(found)
        assert {name: found[name].help for name in LAB_COMMANDS} == LAB_COMMANDS

    def test_without_the_lab(self, capsys, monkeypatch):
        """Without the lab installed, ``--help`` still names its commands with the install line, and running one
        says how to install it (exit 2); the library's commands are unchanged."""
        monkeypatch.setattr(cli_module, "plugin_commands", lambda: {})
        assert main(["--help"]) == 0
        out = capsys.readouterr().out
        assert "train" in out and "needs the lab: pip install -c constraints.txt -e ./plugins/lab" in out
        for name in LAB_COMMANDS:
            assert main([name, "--anything"]) == 2
            line = _error_line(capsys)
            assert f"'{name}' is a command of the lab, which is not installed" in line and "./plugins/lab" in line
        monkeypatch.setattr(cli_module, "entry_points", lambda group, **select: [])
        assert main(["export", "--probe", "."]) == 2
        assert "needs the lab" in _error_line(capsys)

    @pytest.mark.slow  # subprocesses
    def test_subprocess(self, tmp_path):
        env = {**os.environ, "PYTHONWARNINGS": "ignore"}
        run = subprocess.run(
            [sys.executable, "-m", "kornia_ilum", "estimate", "missing.jpg"],
            cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120,
        )
        assert run.returncode == 1
        assert run.stderr == "kornia-ilum: error: cannot read missing.jpg: no such file\n"
        assert run.stdout == ""
        script = Path(sys.executable).with_name("kornia-ilum")  # the console script of pyproject.toml
        run = subprocess.run([str(script), "estimate", "--faces", "x"], capture_output=True, text=True, env=env, timeout=120)
        assert run.returncode == 2
        assert run.stderr.startswith("kornia-ilum: error: argument --faces: invalid choice") and "Traceback" not in run.stderr


class TestExport:
    def test_writes_a_checked_onnx_file(self, tmp_path, capsys) -> None:
        target = tmp_path / "uniform.onnx"
        assert main(["export", "--onnx", str(target), "--estimator", "uniform"]) == 0
        printed = capsys.readouterr().out
        assert f"wrote {target}" in printed and "difference to PyTorch" in printed
        assert target.read_bytes()[:2] == b"\x08\x0a" or target.stat().st_size > 1000
        assert sorted(p.name for p in tmp_path.iterdir()) == ["uniform.onnx"]

    def test_a_scene_branch_exports_checked(self, tmp_path, capsys) -> None:
        """``export --scene FILE --onnx OUT``: the branch's frames in, its strength out, as PyTorch gives them."""
        import onnxruntime as ort
        import safetensors.torch

        from kornia_ilum.estimators import SceneStrength, scene_input

        torch.manual_seed(0)
        branch = SceneStrength().eval()
        weights, target = tmp_path / "scene.safetensors", tmp_path / "scene.onnx"
        safetensors.torch.save_file(branch.state_dict(), str(weights))
        assert main(["export", "--onnx", str(target), "--scene", str(weights)]) == 0
        assert f"wrote {target}" in capsys.readouterr().out
        frames = scene_input(torch.rand(5, 3, 64, 128), torch.tensor([[40.0, 10, 70, 50]] * 5), torch.arange(5))
        got = ort.InferenceSession(str(target), providers=["CPUExecutionProvider"]).run(None,
                                                                                      {"frames": frames.numpy()})
        with torch.no_grad():
            want = branch(frames)
        for g, w in zip(got, want, strict=True):  # a batch of 5: the batch is dynamic
            torch.testing.assert_close(torch.from_numpy(g), w, atol=1e-4, rtol=1e-4)
        assert main(["export", "--onnx", str(tmp_path / "bad.onnx"), "--scene", str(tmp_path / "none")]) == 1
        assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.onnx", "scene.safetensors"]

    def test_int8_is_written_only_if_it_passes_its_lrec_check(self, tmp_path, capsys) -> None:
        target = tmp_path / "sh_int8.onnx"
        status = main(["export", "--onnx", str(target), "--estimator", "sh", "--runtime", "onnx-int8"])
        out, err = capsys.readouterr()
        if status == 0:  # the verdict depends on the CPU's int8 kernels: both outcomes are checked
            assert "runtime onnx-int8" in out and "relative change of L_rec" in out and target.is_file()
        else:
            assert status == 1 and "fails its parity check" in err and not list(tmp_path.iterdir())

    def test_writes_the_probe(self, tmp_path, capsys) -> None:
        assert main(["export", "--probe", str(tmp_path / "missing")]) == 1
        assert main(["export", "--probe", str(tmp_path)]) == 2  # no --cache
        assert main(["export"]) == 2
        assert not list(tmp_path.iterdir())

    def test_bad_targets_are_one_line_errors(self, tmp_path, capsys) -> None:
        assert main(["export", "--onnx", str(tmp_path / "a.txt")]) == 2
        assert main(["export", "--onnx", str(tmp_path / "missing" / "a.onnx")]) == 1
        assert main(["export", "--onnx", str(tmp_path / "a.onnx"), "--estimator", "nope"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 3 and all(line.startswith("kornia-ilum: error: ") for line in err)
        assert not list(tmp_path.iterdir())


class TestVideo:
    """``kornia-ilum video``: the source, its first frame, -o and the options are checked before anything is
    written, and a failed run leaves no output folder behind."""

    #: Fast and independent of the CLI's default detector and runtime.
    FAST = ["--estimator", "uniform", "--detector", "opencv", "--runtime", "eager"]

    @staticmethod
    def _source(tmp_path: Path, kind: str) -> Path:
        """A bad source of ``kind``: missing, an empty folder, a corrupt first frame, no face, an empty video."""
        source = tmp_path / kind
        if kind == "empty_video.avi":
            import cv2

            cv2.VideoWriter(str(source), cv2.VideoWriter_fourcc(*"MJPG"), 10, (16, 16)).release()
        elif kind != "missing":
            source.mkdir()
        if kind == "corrupt":
            (source / "f0.jpg").write_bytes(b"\xff\xd8 not a jpeg")
            _png(source / "f1.png", np.full((64, 96, 3), 90, np.uint8))
        if kind == "faceless":
            for i in range(2):
                _png(source / f"f{i}.png", np.full((64, 96, 3), 90, np.uint8))
        return source

    @pytest.mark.parametrize(
        "kind, message",
        [
            ("missing", "no such video file or folder: "),
            ("empty", "no image (.png, .jpg, .jpeg, .tif, .tiff, .bmp, .webp) in "),
            ("corrupt", "f0.jpg: missing, corrupt or not an image"),
            ("faceless", "no face found in frame 0 by detector 'opencv', and none before it; try --fallback"),
            ("empty_video.avi", "empty_video.avi: an empty or corrupt video"),
        ],
    )
    def test_a_bad_source_leaves_nothing(self, tmp_path, capsys, kind, message):
        source = self._source(tmp_path, kind)
        out = tmp_path / "out" / "frames"  # its parent is missing too
        assert main(["video", str(source), "-o", str(out), *self.FAST]) == 1
        assert message in _error_line(capsys)
        assert not (tmp_path / "out").exists()
        (tmp_path / "out").mkdir()  # an empty folder that existed before the run stays, empty
        assert main(["video", str(source), "-o", str(tmp_path / "out"), *self.FAST]) == 1
        assert message in _error_line(capsys)
        assert (tmp_path / "out").is_dir() and not list((tmp_path / "out").iterdir())

    @pytest.mark.parametrize(
        "options, message",
        [
            (["--time-constant", "-1"], "argument --time-constant: must be a finite number >= 0, got '-1'"),
            (["--time-constant", "inf"], "argument --time-constant: must be a finite number >= 0, got 'inf'"),
            (["--cut-above=nan"], "argument --cut-above: must be a finite number >= 0, got 'nan'"),
            (["--reuse-below", "x"], "argument --reuse-below: must be a finite number >= 0, got 'x'"),
            (["--detect-every", "0"], "argument --detect-every: must be a positive integer, got '0'"),
            (["--fallback", "crop"], "argument --fallback: invalid choice: 'crop'"),
            (["--runtime", "tensorrt"], "argument --runtime: invalid choice: 'tensorrt'"),
            (["--estimator", "nope"], "unknown estimator 'nope'; choose one of: "),
            (["--detector", "haar"], "unknown detector 'haar'; choose one of: "),
        ],
    )
    def test_an_option_error_names_the_option(self, tmp_path, capsys, options, message):
        source = self._source(tmp_path, "faceless")
        out = tmp_path / "out"
        assert main(["video", str(source), "-o", str(out), *self.FAST, *options]) == 2
        line = _error_line(capsys)
        assert message in line and not any(f"{n}_" in line for n in ("time", "cut", "reuse", "detect"))
        assert not out.exists()

    def test_an_existing_file_as_output(self, tmp_path, capsys):
        source = self._source(tmp_path, "faceless")
        taken = tmp_path / "taken.exr"
        taken.write_text("keep me")
        assert main(["video", str(source), "-o", str(taken), *self.FAST]) == 2
        assert _error_line(capsys) == f"kornia-ilum: error: -o/--output {str(taken)!r} is a file; give a folder"
        assert main(["video", str(source), "-o", str(taken / "frames"), *self.FAST]) == 2
        line = _error_line(capsys)
        assert f"{str(taken)!r} is a file; give a folder" in line and "Errno" not in line
        assert taken.read_text() == "keep me"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["faceless", "taken.exr"]

    def test_the_folder_is_made_with_the_first_frame(self, tmp_path, capsys, astronaut):
        source = tmp_path / "clip"
        source.mkdir()
        small = np.ascontiguousarray(astronaut[::2, ::2])
        for i in range(2):
            _png(source / f"f{i}.png", small)
        out = tmp_path / "new" / "frames"
        assert main(["video", str(source), "-o", str(out), *self.FAST]) == 0
        assert "2 frames in " in capsys.readouterr().out
        assert sorted(p.name for p in out.iterdir()) == ["frame_00000.exr", "frame_00001.exr"]
        faceless = self._source(tmp_path, "faceless")
        assert main(["video", str(faceless), "-o", str(out), *self.FAST, "--fallback", "full_image"]) == 0
        assert len(list(out.iterdir())) == 2  # overwritten in place
