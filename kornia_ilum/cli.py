"""The ``kornia-ilum`` command line (also ``python -m kornia_ilum``).

Subcommands:

- ``kornia-ilum estimate [IMAGE ...]``: estimate the lighting of portraits and write it as ``.exr`` or
  ``.hdr`` (and a preview PNG of the three reference spheres); with no image, the astronaut portrait that
  ships with scikit-image (:func:`skimage.data.astronaut`).
- ``kornia-ilum list``: the registered estimators and face detectors, with their metadata.
- ``kornia-ilum synth ...``: the light stage (environments, subject caches).
- ``kornia-ilum train``: train an estimator on the light stage (:mod:`kornia_ilum_lab.train`).
- ``kornia-ilum evaluate``: the paper's tables on the project's held-out split
  (:mod:`kornia_ilum_lab.evaluation`).
- ``kornia-ilum ablate``: the paper's ablations, one training run per row, and their table
  (:mod:`kornia_ilum_lab.ablation`).

Errors print one line, ``kornia-ilum: error: ...``, on stderr, never a traceback (set
``KORNIA_ILUM_DEBUG=1`` to get one), and exit with status 2 for usage errors (bad options) or 1 for
runtime errors (missing or unreadable image, no face, missing weights).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import shlex
import string
import sys
import time
import warnings
from importlib.metadata import entry_points
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import skimage.data
import torch

from kornia_ilum import __version__
from kornia_ilum.api import cached_detector, cached_estimator, estimate_lighting
from kornia_ilum.core.cli import LAB_INSTALL, nonnegative_float, positive_int
from kornia_ilum.core.errors import BaseError, HDRIOError, NoFaceError
from kornia_ilum.core.files import atomic_write
from kornia_ilum.detection import DEFAULT_DETECTOR, describe_detector, list_detectors
from kornia_ilum.estimators import (
    DEFAULT_ESTIMATOR,
    LREC_RTOL,
    PARITY_ATOL,
    RUNTIMES,
    OnnxEstimator,
    SceneStrength,
    create_estimator,
    estimator_info,
    export_scene_onnx,
    list_estimators,
    onnx_model,
    runtime_parity,
)
from kornia_ilum.io import check_ldr, read_ldr

PROG = "kornia-ilum"
_SAMPLE = "astronaut"

_ESTIMATE_HELP = """\
Estimate HDR lighting from portrait photographs: detect the faces, crop them as the paper does, run the
estimator, and write the lighting as an .exr or .hdr file (a 32x32 equal-area mirror ball, linear, in the
units of the photograph; or a lat-long map with --latlong), plus an optional preview PNG of the diffuse,
matte silver and mirror reference spheres. Beside each lighting file, a .json of the same name gives
the main light (direction, solid angle, colour, intensity) and the order-2 SH of the rest, the shape of
ARCore's Environmental HDR (LightingEstimate.dominant_light), and "log_energy_spread": how far the light's
strength may be off (the truth within exp(+-spread) times the estimate's energy for 63 % of faces; null for
estimators without it; docs/questions.rst). With --scene, one strength per photo, its faces' and the whole
photo's fused: "scene_share" (how much of it the photo set, 0 to 1) and "strength_evidence" ("face" below
0.2, "scene" above 0.8, else "both"; "face" without --scene). Prints one line per written file, and the
timing.

output names (-o OUT and --preview PNG):
  OUT is a file name, a directory, or a pattern with the placeholders
    {stem}   the image file's name without its extension ('astronaut' for the built-in sample)
    {face}   the face's index in its image (0 = the first face the detector returns)
  - a directory (one that exists, or a name ending in '/') means DIR/{stem}.EXT;
  - with several images, OUT must be a directory or contain {stem};
  - with --faces all, '_face{face}' is added before the extension when OUT has no {face};
  - a name without extension gets .exr (or --format's); --format must agree with OUT's extension.
  Missing parent folders are created. Default OUT: {stem}.exr in the current folder. --preview PNG
  follows the same rules with the extension .png. Images are processed in order; the first error
  stops the run (files already written stay).

examples:
  kornia-ilum estimate -o astronaut.exr --preview astronaut.png        # the built-in sample
  kornia-ilum estimate photo.jpg --latlong 64 -o light.hdr             # lat-long 64x128 Radiance HDR
  kornia-ilum estimate *.jpg -o out/ --preview out/ --faces all        # out/<stem>_face<i>.exr + .png
  kornia-ilum estimate group.png -o 'light_{stem}_{face}.exr' --faces all --detector yunet
  kornia-ilum estimate photo.jpg --tta 4                               # 4 jittered crops + mirrors, averaged
"""


class _UsageError(Exception):
    """A bad command line (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse, with every usage error as one line ``kornia-ilum: error: ...`` (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        raise _UsageError(f"{message} (see '{self.prog} --help')")


def _add_bench_parser(sub: argparse._SubParsersAction) -> None:
    from kornia_ilum.bench.cli import add_bench_parser  # lazy: the bench loads the estimators' runtimes

    add_bench_parser(sub)


#: The entry-point group of sub-commands that other packages add to ``kornia-ilum``: each names an object with
#: a ``help`` line and ``add_parser(subparsers)`` (the lab's :mod:`kornia_ilum_lab.commands`).
COMMAND_ENTRY_POINT_GROUP = "kornia_ilum.commands"
#: The lab's commands, named in ``--help`` even where the lab is not installed: name -> help line.
LAB_COMMANDS = {
    "synth": "synthesis: lighting environments and light-stage subjects",
    "train": "train an estimator on the light stage",
    "evaluate": "score the estimators and two oracles on the held-out eval set",
    "ablate": "the paper's ablations: one training run per row, and the table",
}
#: The entry-point group of the lab's functions that a library command calls: ``write_training_probe``
#: (``kornia-ilum export --probe``).
LAB_ENTRY_POINT_GROUP = "kornia_ilum.lab"


def plugin_commands() -> dict[str, Any]:
    """The sub-commands that installed packages add (``kornia_ilum.commands`` entry points): name -> command
    (its ``help`` line and ``add_parser``). Loading them imports only each package's light command module."""
    return {ep.name: ep.load() for ep in entry_points(group=COMMAND_ENTRY_POINT_GROUP)}


#: The library's own sub-commands whose modules are imported only when named: name -> (adds the real parser,
#: its help line). A command line that does not name one gets a placeholder with the same help line, so that
#: ``estimate``, ``list`` and ``--help`` start light (``tests/test_cli.py`` checks that the help lines agree).
LAZY_COMMANDS = {
    "bench": (_add_bench_parser, "run time against error: every estimator and runtime, this machine"),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser of ``kornia-ilum`` (used by :func:`main` and the docs).

    Args:
        command: the sub-command that the command line names (``""``: none): of :data:`LAZY_COMMANDS`, only
            its parser is built for real. ``None`` builds every parser (the docs).

    Returns:
        the parser; a usage error raises instead of exiting (:func:`main` prints it in one line).

    Examples:
        >>> args = build_parser("estimate").parse_args(["estimate", "photo.jpg", "--faces", "all"])
        >>> args.command, args.images, args.faces, args.runtime
        ('estimate', ['photo.jpg'], 'all', 'eager')
    """
    parser = _Parser(
        prog=PROG,
        description="HDR lighting from one LDR portrait (LeGendre et al. 2020, 'Learning Illumination from "
        "Diverse Portraits').",
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    est = sub.add_parser(
        "estimate",
        help="estimate the lighting of portraits, write .exr/.hdr and previews",
        description=_ESTIMATE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    est.add_argument(
        "images", nargs="*", metavar="IMAGE",
        help="8/16-bit portrait photographs (PNG, JPEG, TIFF, ...); none: the scikit-image astronaut",
    )
    est.add_argument("-o", "--output", metavar="OUT", help="output file, directory or pattern (see below)")
    est.add_argument("--estimator", metavar="NAME", help="estimator name (default: the registry's default; "
                     "see 'kornia-ilum list')")
    est.add_argument("--detector", metavar="NAME", default=DEFAULT_DETECTOR,
                     help=f"face detector (default: {DEFAULT_DETECTOR}; opencv: the Haar cascade; 'kornia-ilum list')")
    est.add_argument("--faces", choices=("largest", "all", "fused"), default="largest",
                     help="the largest face of each image, all of them, or one lighting fused from all of them "
                     "(a distant light shared by every face; default: largest)")
    est.add_argument("--fallback", choices=("full_image",), default=None,
                     help="when an image has no face, use its largest centred square instead of failing")
    est.add_argument("--preview", metavar="PNG",
                     help="also write a preview PNG of the three reference spheres")
    est.add_argument("--preview-size", type=positive_int, metavar="N", default=128,
                     help="side of each sphere in the preview, which is 3N x N pixels (default: 128)")
    est.add_argument("--format", choices=("exr", "hdr"), default=None,
                     help="file format of the lighting (default: OUT's extension, else exr)")
    est.add_argument("--latlong", type=positive_int, metavar="H", default=None,
                     help="write a lat-long map of H x 2H pixels instead of the 32x32 mirror ball")
    est.add_argument("--half", action="store_true", help="store half floats in the .exr (float32 by default)")
    est.add_argument("--device", default="cpu", help="torch device to run on (default: cpu)")
    est.add_argument("--detect-side", type=_detect_side, metavar="N", default="auto",
                     help="detect faces on a copy of the image at most N pixels on its longer side (faster; the "
                     "smallest face found grows by the same factor), then crop from the full image; 'full' for "
                     "the image itself (default: auto, the detector's own: 240 for yunet, full for opencv)")
    est.add_argument("--runtime", choices=RUNTIMES, default="eager",
                     help="what computes the estimate: eager (PyTorch float32, default), bf16, onnx, onnx-int8, or "
                     "auto (the fastest that runs here and passes its parity check; kornia-ilum bench measures "
                     "them; the ONNX runtimes export once per machine into the cache, ~/.cache/kornia_ilum)")
    est.add_argument("--scene", metavar="FILE", default=None,
                     help="a scene branch's weights (kornia-ilum train --estimator scene): the light's strength "
                     "from the whole photo fused with the faces', one per photo (default: the faces' own)")
    est.add_argument("--tta", type=positive_int, metavar="N", default=None,
                     help="average each face's estimate over N jittered crops and their mirror images "
                     "(2N estimator passes; more stable under the crop; default: off)")

    exp = sub.add_parser(
        "export", help="export an estimator to ONNX (float32 or int8), checked against PyTorch; or the probe",
        description="Export a registered estimator, with its shipped weights, to an ONNX file: sRGB face crops "
        "(B, 3, S, S) in, the estimate's fields out (mirror_ball in the units of the photo, valid, and "
        "log_mirror_ball or sh), with a dynamic batch. The file is written only if it passes its runtime's parity "
        f"check: for --runtime onnx, ONNX Runtime reproduces PyTorch's log(1 + L) within {PARITY_ATOL:g} on a "
        f"probe batch; for --runtime onnx-int8, L_rec on the shipped probe's check part (256 portraits) moves by at most "
        f"{LREC_RTOL:.0%}. Needs pip install 'kornia_ilum[onnx]'. With --probe DIR, write the runtimes' probe "
        "instead (320 training portraits of --cache under --hdri, with their lighting; the int8 calibration).",
    )
    exp.add_argument("--onnx", metavar="FILE", help="the .onnx file to write")
    exp.add_argument("--estimator", metavar="NAME", help="estimator name (default: the registry's default)")
    exp.add_argument("--runtime", choices=("onnx", "onnx-int8"), default="onnx",
                     help="float32 (default) or static int8 calibrated on the shipped probe")
    exp.add_argument("--probe", metavar="DIR", help="write probe.jpg and probe.safetensors into DIR instead")
    exp.add_argument("--scene", metavar="FILE", help="export this scene branch's weights instead (with --onnx): "
                     "frames (B, 5, 128, 128) in, log_energy and spread out, checked against PyTorch")
    exp.add_argument("--cache", nargs="+", default=[], metavar="DIR", help="light-stage caches (with --probe)")
    exp.add_argument("--hdri", nargs="*", default=[], metavar="DIR", help="real maps' folders (with --probe)")

    sub.add_parser("list", help="list the estimators and face detectors",
                   description="List the registered lighting estimators and face detectors, "
                   "with their metadata.")
    vid = sub.add_parser(
        "video", help="the lighting of every frame of a video or an image sequence, one .exr per frame",
        description="Estimate the lighting of every frame of a video file (anything OpenCV opens) or an image "
        "sequence (a folder, or a quoted glob such as 'frames/*.png'), with temporal reuse: the face is "
        "detected every --detect-every frames, a frame whose crop barely changed reuses the last estimate, "
        "and the estimates are smoothed in log space; a cut restarts the smoothing (kornia_ilum.video). The source, "
        "its first frame and the options are checked before anything is written, and the output folder is made "
        "only once the first frame's lighting is known: a run that fails before its first frame is written leaves "
        "nothing behind; a later error stops the run (the frames already written stay).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    vid.add_argument("source", help="a video file, a folder of images, or a quoted glob of images")
    vid.add_argument("-o", "--output", required=True, metavar="DIR",
                     help="the folder that gets frame_00000.exr, frame_00001.exr, ...")
    vid.add_argument("--estimator", default=None, metavar="NAME", help="registered estimator (default: ours)")
    vid.add_argument("--detector", default=DEFAULT_DETECTOR, metavar="NAME",
                     help=f"face detector (default: {DEFAULT_DETECTOR}; opencv: the Haar cascade)")
    vid.add_argument("--detect-every", type=positive_int, default=5, metavar="N",
                     help="detect the face every N frames, and after a cut (default: 5)")
    vid.add_argument("--reuse-below", type=nonnegative_float, default=0.002, metavar="X",
                     help="reuse the last estimate while the crop changed by less than X (default: 0.002)")
    vid.add_argument("--time-constant", type=nonnegative_float, default=2.0, metavar="T",
                     help="smoothing time constant in frames, 0 for none (default: 2)")
    vid.add_argument("--cut-above", type=nonnegative_float, default=0.03, metavar="X",
                     help="a crop change above X is a cut: the smoothing restarts (default: 0.03)")
    vid.add_argument("--fallback", choices=("full_image",), default=None,
                     help="estimate from the centred square while no face was found")
    vid.add_argument("--runtime", choices=RUNTIMES, default="auto",
                     help="what computes the estimates (default: auto, the first float runtime that runs here and "
                     "passes its parity check, ONNX Runtime then bfloat16, exported once per machine into the "
                     "cache: video is where speed counts; int8 is left out, its estimates move more with the crop; "
                     "eager for PyTorch float32; docs/skipping.rst gives the frame rates)")
    vid.add_argument("--scene", metavar="FILE", default=None,
                     help="a scene branch's weights: each estimated frame's strength fused with the whole frame's "
                     "before the smoothing (default: the face's own)")
    plugins = plugin_commands()
    commands = {name: (plugins[name].add_parser, plugins[name].help) for name in plugins}
    commands |= {name: (None, f"{help_line} (needs the lab: {LAB_INSTALL})")
                 for name, help_line in LAB_COMMANDS.items() if name not in plugins}
    commands |= LAZY_COMMANDS
    for name in (*LAB_COMMANDS, *sorted(set(commands) - set(LAB_COMMANDS))):
        add_parser, help_line = commands[name]
        if add_parser is not None and (command is None or command == name):
            add_parser(sub)
        else:
            sub.add_parser(name, help=help_line)
    return parser


# --------------------------------------------------------------------------------------------- outputs
def _detect_side(text: str) -> int | str | None:
    """``--detect-side``: a positive number of pixels, ``full`` (``None``: the image itself) or ``auto``."""
    if text in ("auto", "full"):
        return None if text == "full" else text
    return positive_int(text)


def _check_pattern(pattern: str, option: str) -> set[str]:
    """Placeholders used in ``pattern``; unknown ones or bad braces are usage errors."""
    try:
        fields = {f for _, f, _, _ in string.Formatter().parse(pattern) if f is not None}
    except ValueError as e:
        raise _UsageError(f"{option} {pattern!r}: {e} (write '{{{{' and '}}}}' for literal braces)") from None
    unknown = fields - {"stem", "face"}
    if unknown:
        raise _UsageError(
            f"{option} {pattern!r} has unknown placeholder(s) {', '.join(sorted(unknown))}; "
            "use {stem} and {face}"
        )
    return fields


class _Namer:
    """Turns -o / --preview into one file name per (image stem, face index), following the --help rules."""

    def __init__(self, pattern: str | None, *, option: str, exts: tuple[str, ...], several: bool,
                 faces_all: bool, forced_ext: str | None = None) -> None:
        if pattern is None:
            pattern = "{stem}"
        is_dir = pattern.endswith(("/", os.sep)) or Path(pattern).is_dir()
        fields = _check_pattern(pattern, option)
        if is_dir:
            if fields:
                raise _UsageError(f"{option} {pattern!r} is a directory and cannot hold placeholders")
            pattern = str(Path(pattern) / "{stem}")
            fields = {"stem"}
        elif several and "stem" not in fields:
            raise _UsageError(
                f"with several images, {option} must be a directory or contain {{stem}}, got {pattern!r}"
            )
        suffix = Path(pattern).suffix.lower()
        if suffix:
            if suffix not in exts:
                raise _UsageError(
                    f"{option} must end in {' or '.join(exts)} (or be a directory), got {pattern!r}"
                )
            if forced_ext is not None and suffix != forced_ext:
                raise _UsageError(f"{option} {pattern!r} does not match --format {forced_ext[1:]}")
            stem_part, ext = pattern[: -len(suffix)], pattern[-len(suffix):]
        else:
            stem_part, ext = pattern, forced_ext or exts[0]
        if faces_all and "face" not in fields:
            stem_part += "_face{face}"
        self.pattern = stem_part + ext
        self.ext = ext.lower()

    def __call__(self, stem: str, face: int) -> Path:
        return Path(self.pattern.format(stem=stem, face=face))


# ------------------------------------------------------------------------------------------- commands
def _cmd_list() -> int:
    print(f"Estimators (default: {DEFAULT_ESTIMATOR}):")
    for name in list_estimators():
        try:
            info = estimator_info(name)
        except Exception as e:  # a broken plugin: show it, do not stop the listing
            print(f"  {name}\n      cannot be loaded: {e}")
            continue
        print(f"  {name}\n      {info.description}")
        print(f"      paper: {info.paper}")
        print(f"      input: {info.input_size}x{info.input_size} face crops, sRGB in [0, 1]")
        for w in info.weights:
            print(f"      weights: {w.name} sha256 {w.sha256}")
        if not info.weights:
            why = " (no trained weights yet)" if info.needs_weights else " (needs none)"
            print("      weights: no weights" + why)
        if info.install_hint:
            print(f"      install: {info.install_hint}")
    print(f"Detectors (default: {DEFAULT_DETECTOR}):")
    for name in list_detectors():
        print(f"  {name}\n      {describe_detector(name)}")
    return 0


def _write_main_light(path: Path, light: Any, *, face: int, stem: str, estimator: str) -> Path:
    """Write face ``face``'s main light and ambient (:meth:`LightingEstimate.dominant_light`) as JSON, atomically,
    with the image, the face box and the estimator it came from."""
    spread, share = light.log_energy_spread, light.scene_share
    share = None if share is None else float(share[face])
    evidence = "face" if share is None or share < 0.2 else "scene" if share > 0.8 else "both"
    record = {"image": stem, "face": face, "box": light.boxes[face].tolist(), "estimator": estimator,
              **light.dominant_light().to_dict(face),
              "log_energy_spread": None if spread is None else float(spread[face]),
              "scene_share": share, "strength_evidence": evidence}
    atomic_write(path, lambda tmp: tmp.write_text(json.dumps(record, indent=1) + "\n"))
    return path


def _remove_empty(folders: Sequence[Path]) -> None:
    """Remove ``folders`` (deepest first) while they exist and are empty: what a failed run made and left empty."""
    for folder in folders:
        try:
            folder.rmdir()
        except FileNotFoundError:
            continue
        except OSError:  # not empty (a frame was written), or not removable: leave it and its parents
            return


def _cmd_video(args: argparse.Namespace) -> int:
    """``kornia-ilum video``: one ``.exr`` per frame, and a summary line.

    The options, ``-o`` and the source's first frame are checked before the models load, and the output folder
    (with its missing parents) is made only when the first frame's lighting is known; a failure before the first
    ``.exr`` is written removes the folders this run made, so that it leaves nothing behind.
    """
    from kornia_ilum.video import estimate_video, read_frames  # lazy: OpenCV's video reading is needed here only

    out = Path(args.output)
    missing = [p for p in (out, *out.parents) if not p.exists()]  # the folders this run makes, deepest first
    if out.exists() and not out.is_dir():
        raise _UsageError(f"-o/--output {args.output!r} is a file; give a folder")
    if missing and not missing[-1].parent.is_dir():
        raise _UsageError(f"-o/--output {args.output!r}: {str(missing[-1].parent)!r} is a file; give a folder")
    estimator = args.estimator or DEFAULT_ESTIMATOR
    if estimator not in list_estimators():
        raise _UsageError(f"unknown estimator {estimator!r}; choose one of: {', '.join(list_estimators())}")
    if args.detector not in list_detectors():
        raise _UsageError(f"unknown detector {args.detector!r}; choose one of: {', '.join(list_detectors())}")
    scene = None if args.scene is None else SceneStrength.from_file(args.scene)
    source = read_frames(args.source)
    first = next(source, None)  # a missing source, no image, an unreadable first frame: fail before any work
    if first is None:
        raise HDRIOError(f"no frame in {args.source}")
    t0 = time.perf_counter()
    frames = detected = estimated = cuts = 0
    stream = estimate_video(itertools.chain([first], source), estimator=estimator, detector=args.detector,
                            detect_every=args.detect_every, reuse_below=args.reuse_below,
                            time_constant=args.time_constant, cut_above=args.cut_above, fallback=args.fallback,
                            runtime=args.runtime, scene=scene)
    try:
        for frame in stream:
            if not frames:
                try:
                    out.mkdir(parents=True, exist_ok=True)
                except OSError as e:
                    raise HDRIOError(f"cannot make the folder {out}: {e.strerror or e}") from None
            frame.lighting.save(out / f"frame_{frame.index:05d}.exr")
            frames, detected, estimated = frames + 1, detected + frame.detected, estimated + frame.estimated
            cuts += frame.cut
    except BaseException as e:
        _remove_empty(missing)  # the folders this run made, if no frame was written into them
        if isinstance(e, NoFaceError):  # the hint names the option, not the Python argument
            raise NoFaceError(_as_options(str(e))) from None
        raise
    seconds = time.perf_counter() - t0
    print(f"{frames} frames in {seconds:.2f} s ({frames / max(seconds, 1e-9):.1f} fps, .exr writes included): "
          f"detected on {detected}, estimated on {estimated}, {cuts} cut(s); wrote {out}/frame_*.exr")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    if args.probe is not None:
        return _cmd_export_probe(args)
    if args.onnx is None:
        raise _UsageError("export needs --onnx FILE (or --probe DIR)")
    name = args.estimator or DEFAULT_ESTIMATOR
    if name not in list_estimators():
        raise _UsageError(f"unknown estimator {name!r}; choose one of: {', '.join(list_estimators())}")
    target = Path(args.onnx)
    if target.suffix.lower() != ".onnx":
        raise _UsageError(f"--onnx must name a .onnx file, got {args.onnx!r}")
    if not target.parent.is_dir():
        raise HDRIOError(f"cannot write {target}: the folder {target.parent} does not exist")
    t0 = time.perf_counter()
    if args.scene is not None:
        data = export_scene_onnx(SceneStrength.from_file(args.scene), target)
        print(f"wrote {target} ({len(data) / 2**20:.1f} MiB, scene branch {args.scene}, input (B, 5, 128, 128); "
              f"ONNX Runtime within {PARITY_ATOL:g} of PyTorch; {_ms(t0)})")
        return 0
    estimator = create_estimator(name)
    model = onnx_model(estimator, args.runtime, cache=False)
    size = estimator.info.input_size
    value, tol, passed = runtime_parity(estimator, OnnxEstimator(model, runtime=args.runtime), args.runtime)
    what = ("max |log(1 + L)| difference to PyTorch" if args.runtime == "onnx"
            else "largest relative change of L_rec on the probe's check part")
    if not passed:
        raise RuntimeError(f"the {args.runtime} export of {name!r} fails its parity check: {what} {value:.3g} "
                           f"(at most {tol:g}); nothing was written")
    atomic_write(target, lambda tmp: tmp.write_bytes(model))
    print(f"wrote {target} ({len(model) / 2**20:.1f} MiB, estimator {name!r}, runtime {args.runtime}, input "
          f"(B, 3, {size}, {size}); {what} {value:.2g}; {_ms(t0)})")
    return 0


def _cmd_export_probe(args: argparse.Namespace) -> int:
    found = entry_points(group=LAB_ENTRY_POINT_GROUP, name="write_training_probe")
    if not found:
        raise _UsageError(f"export --probe renders light-stage portraits, which needs the lab: {LAB_INSTALL}")
    write_training_probe = next(iter(found)).load()  # the lab's kornia_ilum_lab.train.data.write_training_probe

    folder = Path(args.probe)
    if not folder.is_dir():
        raise HDRIOError(f"cannot write the probe into {folder}: no such folder")
    if not args.cache:
        raise _UsageError("--probe needs --cache DIR ... (light-stage caches with train subjects)")
    t0 = time.perf_counter()
    meta = write_training_probe(folder, args.cache, hdri=args.hdri)
    print(f"wrote {folder / 'probe.jpg'} and {folder / 'probe.safetensors'} ({meta['samples']} training portraits "
          f"of {len(meta['subjects'])} subjects, skin tones {meta['skin_tones']}; {_ms(t0)})")
    return 0


#: The API's hints (Python arguments) and the command line's options that say the same.
_OPTION_HINTS = (("detector='yunet'", "--detector yunet"), ("detector='none'", "--detector none"),
                 ("fallback='full_image'", "--fallback full_image"))


def _as_options(message: str) -> str:
    """An API error message with its Python-argument hints written as command-line options."""
    for python, option in _OPTION_HINTS:
        message = message.replace(python, option)
    return message


def _cmd_estimate(args: argparse.Namespace) -> int:
    several = len(args.images) > 1
    faces_all = args.faces == "all"
    forced = f".{args.format}" if args.format else None
    out = _Namer(args.output, option="-o", exts=(".exr", ".hdr"), several=several, faces_all=faces_all,
                 forced_ext=forced)
    if args.half and out.ext != ".exr":
        raise _UsageError("--half applies to .exr files only")
    preview = (
        _Namer(args.preview, option="--preview", exts=(".png",), several=several, faces_all=faces_all)
        if args.preview is not None else None
    )
    estimator = args.estimator or DEFAULT_ESTIMATOR
    if estimator not in list_estimators():
        raise _UsageError(f"unknown estimator {estimator!r}; choose one of: {', '.join(list_estimators())}")
    if args.detector not in list_detectors():
        raise _UsageError(f"unknown detector {args.detector!r}; choose one of: {', '.join(list_detectors())}")
    try:
        device = torch.device(args.device)
    except RuntimeError as e:
        raise _UsageError(f"--device {args.device!r}: {e}") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise _UsageError(f"--device {args.device!r}: CUDA is not available in this PyTorch build or machine")
    stems = [Path(p).stem for p in args.images] or [_SAMPLE]
    if several and len(set(stems)) < len(stems):
        dup = next(s for s in stems if stems.count(s) > 1)
        raise _UsageError(
            f"several images are named {dup!r} (their outputs would collide); run them separately"
        )
    for p in args.images:  # fail before any work (the models load next) when a file is no readable image
        check_ldr(p)

    t0 = time.perf_counter()
    scene = None if args.scene is None else SceneStrength.from_file(args.scene).to(device)
    chosen = cached_estimator(estimator, device, args.runtime).runtime  # built once (missing weights fail here)
    detector = cached_detector(args.detector, device, args.detect_side)
    print(f"loaded estimator {estimator!r} (runtime {chosen}) and detector {args.detector!r} in {_ms(t0)}")

    written: set[Path] = set()
    for path, stem in zip(args.images or [None], stems):
        t0 = time.perf_counter()
        image = skimage.data.astronaut() if path is None else read_ldr(path)
        stages = {"read": 1e3 * (time.perf_counter() - t0)}
        try:
            light = estimate_lighting(
                image, estimator=estimator, detector=detector, faces=args.faces, fallback=args.fallback,
                device=device, tta=args.tta, runtime=args.runtime, on_stage=stages.__setitem__, scene=scene,
            )
        except NoFaceError as e:  # the API's hints name Python arguments; here they are options
            raise NoFaceError(_as_options(str(e))) from None
        for key in ("write", "preview"):
            stages[key] = 0.0
        for face in range(len(light)):
            files = [(out(stem, face), "lighting")] + ([(preview(stem, face), "preview")] if preview else [])
            for target, kind in files:
                if target in written or (kind == "lighting" and target.with_suffix(".json") in written):
                    raise RuntimeError(
                        f"{target} would be written twice in this run; add {{stem}} or {{face}} to the name"
                    )
                written.update([target] + ([target.with_suffix(".json")] if kind == "lighting" else []))
                target.parent.mkdir(parents=True, exist_ok=True)
                box = ", ".join(f"{v:.0f}" for v in light.boxes[face].tolist())
                t1 = time.perf_counter()
                if kind == "lighting":
                    light.save(target, index=face, latlong_height=args.latlong, half=args.half)
                    main_light = _write_main_light(target.with_suffix(".json"), light, face=face, stem=stem,
                                                   estimator=estimator)
                    what = (
                        f"lat-long {args.latlong}x{2 * args.latlong}" if args.latlong else "mirror ball 32x32"
                    )
                    stages["write"] += 1e3 * (time.perf_counter() - t1)
                    print(f"wrote {target} ({what}, face {face} of {stem}, box [{box}]) and {main_light.name} "
                          "(main light and ambient SH)")
                else:
                    light.preview(target, index=face, size=args.preview_size)
                    stages["preview"] += 1e3 * (time.perf_counter() - t1)
                    n = args.preview_size
                    print(f"wrote {target} (preview {3 * n}x{n}: diffuse, matte silver, mirror spheres)")
        if not preview:
            del stages["preview"]
        split = ", ".join(f"{k} {v:.0f} ms" for k, v in stages.items())
        print(
            f"{stem}: {len(light)} face{'s' if len(light) != 1 else ''} (detector {args.detector}, estimator "
            f"{estimator}, runtime {chosen}{f', tta {args.tta}' if args.tta else ''}): {split}; total {_ms(t0)}"
        )
    return 0


def _ms(t0: float) -> str:
    return f"{1e3 * (time.perf_counter() - t0):.0f} ms"


# ----------------------------------------------------------------------------------------------- main
def _error(message: str, status: int) -> int:
    print(f"{PROG}: error: {' '.join(str(message).split())}", file=sys.stderr)
    return status


def _warn(message, category, filename, lineno, *where) -> None:  # noqa: ARG001
    # warnings.showwarning's signature; ``where`` is its (file, line), which a one-line warning leaves out
    print(f"{PROG}: warning: {' '.join(str(message).split())}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``kornia-ilum`` with ``argv`` (default: ``sys.argv[1:]``); returns the exit status.

    Args:
        argv: the command line's arguments, without the program's name.

    Returns:
        the exit status: 0, 1 for a runtime error, 2 for a usage error, 130 when interrupted (an error is one
        line on stderr; ``KORNIA_ILUM_DEBUG=1`` raises runtime errors instead).

    Examples:
        >>> main(["estimate", "--faces", "many"])
        2
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    command = next((a for a in argv if not a.startswith("-")), "")
    debug = bool(os.environ.get("KORNIA_ILUM_DEBUG"))
    with warnings.catch_warnings():
        warnings.showwarning = _warn
        try:
            if command in LAB_COMMANDS and command not in plugin_commands():
                raise _UsageError(f"'{command}' is a command of the lab, which is not installed: {LAB_INSTALL}")
            args = build_parser(command).parse_args(argv)
            args.command_line = shlex.join(["kornia-ilum", *argv])  # what the lab's figures record
            if getattr(args, "func", None) is not None:  # the lab's commands and the lazy ones
                return args.func(args)
            if args.command == "export":
                return _cmd_export(args)
            if args.command == "video":
                return _cmd_video(args)
            return _cmd_list() if args.command == "list" else _cmd_estimate(args)
        except SystemExit as e:  # --help / --version
            return e.code if isinstance(e.code, int) else 0
        except _UsageError as e:
            return _error(str(e), 2)
        except KeyboardInterrupt:
            return _error("interrupted", 130)
        except Exception as e:  # every runtime failure: one line, no traceback
            if debug:
                raise
            known = isinstance(e, (BaseError, OSError, RuntimeError, ValueError))
            return _error(str(e) if known else f"{type(e).__name__}: {e}", 1)
