"""The docs: the README's Sphinx build (warnings as errors; the gallery's examples run at build time), and the
rendered pages in headless Chromium (Debian's ``chromium`` and ``chromium-driver``, driven by Selenium): a
screenshot of the index, an API page and a gallery page, with no broken image, no broken link and no raw LaTeX
in the index's table of contents. And what the README and the API pages say of the code: the README stays short,
its ``estimate_lighting`` signature is the function's, and every op of the op subpackages has its module twin
(``docs/api/index.rst``)."""

from __future__ import annotations

import ast
import importlib
import inspect
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")

#: The pages opened in the browser: the index, an API page, and the gallery's compositing example.
PAGES = ("index.html", "api/geometry.html", "auto_examples/plot_composite_virtual_object.html")

#: Every image, and every link to another page of the docs, that the pages hold.
BROKEN_IMAGES = "return Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src)"
LINKS = "return Array.from(document.querySelectorAll('a[href]')).map(a => a.href)"


@pytest.fixture(scope="module")
def html(tmp_path_factory) -> Path:
    """The README's docs build (``sphinx -W --keep-going``), into a temporary folder."""
    out = tmp_path_factory.mktemp("docs")
    run = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", "-d",
                          str(out / "doctrees"), str(ROOT / "docs"), str(out / "html")],
                         capture_output=True, text=True, timeout=1800, check=False)
    assert run.returncode == 0, run.stderr[-6000:]
    return out / "html"


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    from selenium import webdriver  # lazy: only this test drives a browser
    from selenium.webdriver.chrome.service import Service

    assert CHROMIUM.is_file() and CHROMEDRIVER.is_file(), (
        "the browser test needs Debian's chromium and chromium-driver (the README's test command installs them)")
    profile = tmp_path_factory.mktemp("chromium")
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,1600",
                 f"--user-data-dir={profile}", f"--crash-dumps-dir={profile}", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    home = {"HOME": str(profile), "XDG_CONFIG_HOME": str(profile), "XDG_CACHE_HOME": str(profile)}
    service = Service(str(CHROMEDRIVER), env={**os.environ, **home})  # nothing written into the user's home
    driver = webdriver.Chrome(service=service, options=options)
    yield driver
    driver.quit()


def _local_target(url: str) -> tuple[Path, str] | None:
    """A ``file://`` link's file and fragment; ``None`` for any other scheme (not fetched: no network)."""
    parsed = urlparse(url)
    return (Path(unquote(parsed.path)), parsed.fragment) if parsed.scheme == "file" else None


@pytest.mark.slow
def test_the_docs_render_in_chromium_without_broken_images_or_links(html, browser, tmp_path) -> None:
    from PIL import Image

    for page in PAGES:
        path = html / page
        assert path.is_file(), f"{page} was not built"
        browser.get(path.as_uri())
        assert browser.execute_script("return document.readyState") == "complete"
        assert browser.execute_script(BROKEN_IMAGES) == [], f"broken images on {page}"
        for url in browser.execute_script(LINKS):
            target = _local_target(url)
            if target is None:
                continue
            file, fragment = target
            assert file.exists(), f"{page} links to a missing {file}"
            if fragment and file.suffix == ".html":
                text = file.read_text(encoding="utf-8")
                assert f'id="{fragment}"' in text, f"{page} links to a missing anchor {file.name}#{fragment}"
        shot = tmp_path / (page.replace("/", "_") + ".png")
        assert browser.save_screenshot(str(shot))
        pixels = np.asarray(Image.open(shot).convert("L"), dtype=np.float32)
        assert pixels.shape[1] >= 1000 and pixels.std() > 10, f"{page} renders blank"
        if page == "index.html":
            toc = browser.execute_script(
                "return Array.from(document.querySelectorAll('.toctree-wrapper')).map(e => e.innerText).join()")
            assert "\\(" not in toc and "mathrm" not in toc, "raw LaTeX in the index's table of contents"
    gallery = browser.execute_script("return Array.from(document.images).filter(i => i.naturalWidth > 300).length")
    assert gallery >= 1, "the compositing example shows no figure"


# --- the README and the API pages against the code ----------------------------------------------------------

#: The README is what a newcomer reads in two minutes; tables, training commands and measurements live in docs/.
README_MAX_LINES = 150


def test_the_readme_is_short() -> None:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines; move details to docs/"


def _spelled_signatures(path: Path) -> list[ast.FunctionDef]:
    """Every ``def estimate_lighting(...)`` written out in ``path`` (a Markdown or reST code block), parsed: from
    its first line, dedented, as many lines as make a complete definition."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found = []
    for start, line in enumerate(lines):
        if "def estimate_lighting(" not in line:
            continue
        indent = len(line) - len(line.lstrip())
        for end in range(start + 1, min(start + 12, len(lines)) + 1):
            try:
                tree = ast.parse(textwrap.dedent("\n".join(l[indent:] for l in lines[start:end])))
            except SyntaxError:
                continue
            found.append(tree.body[0])
            break
        else:
            raise AssertionError(f"{path.name}:{start + 1}: an estimate_lighting signature that does not parse")
    return found


def _parameters(node: ast.FunctionDef) -> list[tuple[str, inspect._ParameterKind, object]]:
    """(name, kind, default) of a parsed definition, with ``inspect``'s kinds and literal defaults."""
    args = node.args
    positional = [(a, inspect.Parameter.POSITIONAL_ONLY) for a in args.posonlyargs]
    positional += [(a, inspect.Parameter.POSITIONAL_OR_KEYWORD) for a in args.args]
    defaults = [inspect.Parameter.empty] * (len(positional) - len(args.defaults)) + [
        ast.literal_eval(d) for d in args.defaults]
    out = [(a.arg, kind, default) for (a, kind), default in zip(positional, defaults)]
    if args.vararg:
        out.append((args.vararg.arg, inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.empty))
    out += [(a.arg, inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.empty if d is None else ast.literal_eval(d))
            for a, d in zip(args.kwonlyargs, args.kw_defaults)]
    if args.kwarg:
        out.append((args.kwarg.arg, inspect.Parameter.VAR_KEYWORD, inspect.Parameter.empty))
    return out


def test_the_readme_signature_of_estimate_lighting_is_the_code_s() -> None:
    """The ``def estimate_lighting(...)`` block of the README (and any that the docs spell out) has the
    function's parameters: names, order, kinds and defaults, and its return type."""
    import kornia_ilum  # lazy: the other tests of this file build the docs in a subprocess

    actual = inspect.signature(kornia_ilum.estimate_lighting)
    expected = [(p.name, p.kind, p.default) for p in actual.parameters.values()]
    readme = _spelled_signatures(ROOT / "README.md")
    assert len(readme) == 1, "README.md must spell out estimate_lighting's signature once, in a python block"
    pages = [p for p in (ROOT / "docs").rglob("*.rst") if "_build" not in p.parts and "generated" not in p.parts]
    for where, node in [("README.md", readme[0])] + [(p.name, n) for p in pages for n in _spelled_signatures(p)]:
        assert _parameters(node) == expected, f"{where}: estimate_lighting's parameters differ from the code's"
        returns = ast.unparse(node.returns) if node.returns else None
        assert returns == str(actual.return_annotation), f"{where}: estimate_lighting's return type"


#: The subpackages whose public functions are ops (docs/api/index.rst): each op has an ``nn.Module`` twin.
OP_SUBPACKAGES = ("geometry", "filters", "color", "render", "sh", "metrics")

#: The public functions of the op subpackages that are not ops, and why (docs/api/index.rst names the kinds).
NOT_OPS = {
    **dict.fromkeys(
        ["geometry.check_layout", "geometry.check_lighting", "render.check_brdf", "render.check_eps",
         "render.check_sphere_lighting", "render.check_sphere_sizes", "metrics.check_lighting_pair",
         "render.gamma_knee"],
        "an argument check (or a checked name turned into its number): nothing to transform"),
    **dict.fromkeys(
        ["filters.soft_clip_unchecked", "color.gamma_encode_unchecked", "render.relight_product",
         "geometry.resample_bilinear"],
        "the unchecked kernel of an op that has a twin (SoftClip, GammaEncode, Relight, the resamplers)"),
    **dict.fromkeys(
        ["geometry.latlong_angles", "geometry.latlong_directions", "geometry.latlong_solid_angles",
         "geometry.mirror_ball_directions", "geometry.mirror_ball_uv", "geometry.mirror_ball_valid",
         "geometry.mirror_ball_solid_angles", "geometry.orientation_map", "geometry.grid_overlaps",
         "color.centre_weights", "render.mirror_ball_downsample_matrix", "render.sphere_reflectance_field",
         "render.shared_sphere_field"],
        "a constant built from sizes (a grid, mask, solid angles, resampling matrix or reflectance field): no "
        "input to transform; the twins hold these as buffers"),
    **dict.fromkeys(
        ["geometry.angles_to_latlong_pixel", "geometry.direction_to_latlong", "geometry.direction_to_mirror_ball",
         "geometry.latlong_to_direction", "geometry.mirror_ball_pixel_index", "geometry.mirror_ball_to_direction",
         "geometry.pixel_to_uv", "geometry.uv_to_pixel", "sh.sh_basis"],
        "a coordinate map of points or directions (as Kornia's geometry conversions), not of images"),
    **dict.fromkeys(
        ["geometry.mirror_ball_to_lights", "geometry.lights_to_mirror_ball", "geometry.latlong_for_tool",
         "sh.sh_to_arcore", "sh.sh_from_arcore", "sh.sh_to_deca", "sh.sh_from_deca", "sh.sh_to_dpr",
         "sh.sh_from_dpr", "sh.sh_to_sfsnet", "sh.sh_from_sfsnet", "sh.sh_to_webxr", "sh.sh_from_webxr"],
        "a layout adapter: the same numbers in another layout, or another project's or tool's convention"),
    **dict.fromkeys(
        ["render.prepare_sparse", "render.sparse_kept", "render.kept_lights", "render.light_norms",
         "render.sphere_plan", "render.render_plan"],
        "a step of a twin's precomputed state (RelightSparse, Relight, RenderSpheres and the losses hold it)"),
    "color.encode_srgb8": "8-bit codes for writing a file (uint8, not differentiable): I/O, not an op",
}


def _twins(module) -> set[str]:
    """The functions of ``module`` that an ``nn.Module`` of its ``__all__`` is the twin of: by its docstring
    ("Module twin of :func:`name`") or by its name (``CamelCase`` of ``snake_case``, as Kornia's re-exports)."""
    import torch  # lazy: as kornia_ilum above

    twins = set()
    for name in module.__all__:
        cls = getattr(module, name)
        if inspect.isclass(cls) and issubclass(cls, torch.nn.Module):
            twins.add(name.lower())
            named = re.match(r"Module twin of :func:`~?([\w.]+)`", inspect.getdoc(cls) or "")
            if named:
                twins.add(named.group(1).rsplit(".", 1)[-1].replace("_", ""))
    return twins


def test_every_op_has_a_module_twin() -> None:
    """docs/api/index.rst: in the op subpackages every public function is an op with an ``nn.Module`` twin, or
    one of :data:`NOT_OPS`, each with the reason. A new function without a twin fails here until it gets one
    or a reason; a stale entry of :data:`NOT_OPS` fails too."""
    missing, functions = [], set()
    for package in OP_SUBPACKAGES:
        module = importlib.import_module(f"kornia_ilum.{package}")
        twins = _twins(module)
        for name in module.__all__:
            if not inspect.isfunction(getattr(module, name)):
                continue
            functions.add(f"{package}.{name}")
            if name.replace("_", "") not in twins and f"{package}.{name}" not in NOT_OPS:
                missing.append(f"kornia_ilum.{package}.{name}")
    assert missing == [], "ops without an nn.Module twin (add one, or a reason to NOT_OPS)"
    assert sorted(set(NOT_OPS) - functions) == [], "NOT_OPS names functions that are not public any more"
    twinned = sorted(n for n in NOT_OPS if n.split(".")[1].replace("_", "")
                     in _twins(importlib.import_module(f"kornia_ilum.{n.split('.')[0]}")))
    assert twinned == [], "NOT_OPS names functions that have a twin"


def test_the_api_index_names_the_op_subpackages() -> None:
    """The index's sentence on twins names exactly the subpackages that the test above enumerates."""
    text = " ".join((ROOT / "docs" / "api" / "index.rst").read_text(encoding="utf-8").split())
    sentence = next(s for s in re.split(r"(?<=\.)\s", text) if "twin" in s)
    assert sorted(re.findall(r":mod:`~?kornia_ilum\.(\w+)`", sentence)) == sorted(OP_SUBPACKAGES), sentence
