"""The architecture's rules, checked mechanically: the layer contract catches what it is meant to catch, no
module imports another module's private names, every import inside a function says why it is there, and
the conventions page is the one reference, word for word the shared conventions.

The contract itself (``[tool.importlinter]`` in ``pyproject.toml``) is run by ``lint-imports`` in the README's
test command; the tests here show that it fails on an upward import and on a cycle.
"""

from __future__ import annotations

import ast
import copy
import difflib
import io
import re
import tokenize
import tomllib
from pathlib import Path

import grimp
import pytest
from importlinter.contracts.acyclic_siblings import AcyclicSiblingsContract
from importlinter.contracts.forbidden import ForbiddenContract
from importlinter.contracts.layers import LayersContract
from importlinter.configuration import configure as configure_import_linter

from tests.conftest import SHARED_DATA

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "kornia_ilum": ROOT / "kornia_ilum",
    "kornia_ilum_lab": ROOT / "plugins" / "lab" / "kornia_ilum_lab",
    "kornia_ilum_sh": ROOT / "plugins" / "sh" / "kornia_ilum_sh",
    "kornia_ilum_sipr": ROOT / "plugins" / "sipr" / "kornia_ilum_sipr",
    "kornia_ilum_uniform": ROOT / "plugins" / "uniform" / "kornia_ilum_uniform",
}
_CONTRACT_TYPES = {"layers": LayersContract, "acyclic_siblings": AcyclicSiblingsContract,
                   "forbidden": ForbiddenContract}


def _modules() -> dict[str, Path]:
    """Every module of the library and its plugins by dotted name."""
    found = {}
    for package, folder in PACKAGES.items():
        for path in folder.rglob("*.py"):
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
            found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _absolute(module: str, path: Path, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")[: len(module.split(".")) - node.level + (path.name == "__init__.py")]
    return ".".join(base + ([node.module] if node.module else []))


# --------------------------------------------------------------------------------------------------- contract
@pytest.fixture(scope="module")
def contracts() -> list:
    configure_import_linter()  # import-linter's own settings (its graph builder and timer), as lint-imports does
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    session = {"root_packages": config["root_packages"]}
    return [
        _CONTRACT_TYPES[c["type"]](name=c["name"], session_options=session,
                                   contract_options={k: v for k, v in c.items() if k not in ("name", "type")})
        for c in config["contracts"]
    ]


@pytest.fixture(scope="module")
def graph() -> grimp.ImportGraph:
    """The import graph of the library and its plugins, as ``lint-imports`` builds it."""
    return grimp.build_graph(*PACKAGES, cache_dir=None)


def _with_import(graph: grimp.ImportGraph, importer: str, imported: str) -> grimp.ImportGraph:
    """A copy of ``graph`` with one more import."""
    changed = copy.deepcopy(graph)
    changed.add_import(importer=importer, imported=imported, line_number=1, line_contents=f"import {imported}")
    return changed


def _broken(contracts: list, graph: grimp.ImportGraph) -> list[str]:
    return [c.name for c in contracts if not c.check(graph, verbose=False).kept]


def test_the_contract_holds(contracts, graph) -> None:
    """Also what makes the tests below meaningful: each breaks a contract that holds."""
    assert _broken(contracts, graph) == []


@pytest.mark.parametrize("importer, imported", [
    ("kornia_ilum.core.check", "kornia_ilum.cli"),           # the bottom layer reaching the top
    ("kornia_ilum.render.spheres", "kornia_ilum.metrics"),   # one layer up
    ("kornia_ilum.geometry.resample", "kornia_ilum.detection.crop"),  # between independent siblings
    ("kornia_ilum.estimators.base", "kornia_ilum.api"),      # the models never reach the one-call API
])
def test_an_upward_import_breaks_the_layers(contracts, graph, importer, imported) -> None:
    assert "kornia_ilum layers" in _broken(contracts, _with_import(graph, importer, imported))


@pytest.mark.parametrize("importer, imported", [
    ("kornia_ilum.api", "kornia_ilum_lab.synth.lightstage"),      # the library reaching into the lab
    ("kornia_ilum.bench.run", "kornia_ilum_lab.evaluation"),     # even where the bench wants the error
    ("kornia_ilum_sh.estimator", "kornia_ilum_lab.train"),        # a plugin's estimator, too
])
def test_the_library_never_imports_the_lab(contracts, graph, importer, imported) -> None:
    """The two houses: a deliberate import of the lab from the library breaks the contract (lint-imports in CI)."""
    assert "the library never imports the lab" in _broken(contracts, _with_import(graph, importer, imported))


def test_the_lab_has_its_layers(contracts, graph) -> None:
    changed = _with_import(graph, "kornia_ilum_lab.synth.lightstage.olat", "kornia_ilum_lab.train.recipes")
    assert "kornia_ilum_lab layers" in _broken(contracts, changed)


def test_a_cycle_breaks_the_contract(contracts, graph) -> None:
    # the loop imports the recipes; the recipes importing the loop back closes a cycle
    broken = _broken(contracts, _with_import(graph, "kornia_ilum_lab.train.recipes", "kornia_ilum_lab.train.loop"))
    assert any(name.startswith("no import cycles") for name in broken), broken


def test_inference_never_imports_training(contracts, graph) -> None:
    changed = _with_import(graph, "kornia_ilum_sh.estimator", "kornia_ilum_sh.recipe")
    assert any(name.startswith("inference never imports training") for name in _broken(contracts, changed))


# ------------------------------------------------------------------------------------------------ source rules
def test_no_module_imports_another_modules_private_names() -> None:
    """A name that another module needs is public in its home (``__dunder__`` names are not private)."""
    modules, reach_ins = _modules(), []
    for module, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom):
                continue
            source = _absolute(module, path, node)
            if source.split(".")[0] not in PACKAGES or source == module:
                continue
            for alias in node.names:
                private = alias.name.startswith("_") and not alias.name.endswith("__")
                if private and f"{source}.{alias.name}" not in modules:
                    reach_ins.append(f"{path.relative_to(ROOT)}:{node.lineno}: {source}.{alias.name}")
    assert reach_ins == []


def test_every_import_inside_a_function_says_why() -> None:
    """Imports belong at the top of a module, where they show the dependency graph. One inside a function
    (to keep ``import kornia_ilum`` cheap: Mitsuba, OpenImageIO, matplotlib...) carries a comment saying why,
    on its line or the line above."""
    silent = []
    for path in _modules().values():
        lines = path.read_text().splitlines()
        for function in ast.walk(ast.parse("\n".join(lines))):
            if not isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(function):
                if isinstance(node, (ast.Import, ast.ImportFrom)):
                    here, above = lines[node.lineno - 1], lines[node.lineno - 2].strip()
                    if "#" not in here and not above.startswith("#"):
                        silent.append(f"{path.relative_to(ROOT)}:{node.lineno}: {here.strip()}")
    assert silent == []


def test_the_conventions_page_is_the_one_reference() -> None:
    old_name = "SPEC" + ".md"  # the shared file's name, which the project's files cite as docs/conventions.rst
    files = [p for folder in ("kornia_ilum", "plugins", "docs", "tests", "benchmarks")
             for p in (ROOT / folder).rglob("*") if p.suffix in (".py", ".rst", ".md", ".toml")]
    files += [ROOT / "README.md"]
    citing = [str(p.relative_to(ROOT)) for p in files if "_build" not in p.parts and old_name in p.read_text()]
    assert citing == []


#: A measured time or speed: "0.3 ms", "24 min", "2.1 s", "200 samples/s", "7x faster", "120 GFLOP/s" (not
#: a rate unit such as "s/view", nor a progress line's "ETA 1 min").
_TIMING = re.compile(r"\b\d+(?:\.\d+)?\s?(?:ms|µs|us)\b|(?<!ETA )\b\d+(?:\.\d+)?\s?(?:min|s)\b(?! ?/)|samples/s"
                     r"|\d+(?:\.\d+)?\s?(?:x|times) (?:faster|slower)|[GM]FLOP/s|[GM]B/s")


def test_docstrings_and_comments_quote_no_timings() -> None:
    """Measured times live in docs/ and the benchmarks, where they are measured again; docstrings and comments
    keep the complexity and the reason for a choice."""
    quoted = []
    for path in _modules().values():
        source = path.read_text()
        texts = [(node.lineno if hasattr(node, "lineno") else 1, ast.get_docstring(node, clean=False) or "")
                 for node in ast.walk(ast.parse(source))
                 if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))]
        texts += [(tok.start[0], tok.string) for tok in tokenize.generate_tokens(io.StringIO(source).readline)
                  if tok.type == tokenize.COMMENT]
        quoted += [f"{path.relative_to(ROOT)}:{line}: {m.group()!r}" for line, text in texts
                   for m in _TIMING.finditer(text)]
    assert quoted == []


#: Modules without a test module of their own, and why.
_UNTESTED_ALONE = {
    "kornia_ilum/core/errors.py": "exception classes only; every error is raised and caught by the other tests",
    "plugins/lab/kornia_ilum_lab/synth/lightstage/gbuffer.py": "a dataclass; its one property has a doctest",
}


def test_tests_mirror_the_package() -> None:
    """``kornia_ilum/a/b.py`` is tested in ``tests/a/test_b.py`` (a private ``_b.py`` in ``test_b.py``), the lab's
    ``plugins/lab/kornia_ilum_lab/a/b.py`` in ``tests/lab/a/test_b.py``; the estimator plugins, one package each,
    in ``tests/plugins/test_<plugin>.py``."""
    missing = []
    for root, tests in ((ROOT / "kornia_ilum", ROOT / "tests"),
                        (ROOT / "plugins" / "lab" / "kornia_ilum_lab", ROOT / "tests" / "lab")):
        for path in sorted(root.rglob("*.py")):
            rel = path.relative_to(ROOT)
            if path.stem in ("__init__", "__main__") or str(rel) in _UNTESTED_ALONE:
                continue
            test = tests / path.parent.relative_to(root) / f"test_{path.stem.lstrip('_')}.py"
            if not test.is_file():
                missing.append(f"{rel} -> {test.relative_to(ROOT)}")
    missing += [f"plugins/{name} -> tests/plugins/test_{name}.py" for name in ("sh", "sipr", "uniform")
                if not (ROOT / "tests" / "plugins" / f"test_{name}.py").is_file()]
    assert missing == []


def test_the_library_stays_small() -> None:
    """The library a user installs holds at most 7,100 lines of code (docstrings, comments and blank lines aside;
    ``benchmarks/count_lines.py``): what makes the estimators is the lab's. (7,000 until issue 47 brought the
    scene branch into the library: its network and input, one strength per photo, and their use by
    ``estimate_lighting``, the tracker and the CLI.)"""
    import importlib.util

    spec = importlib.util.spec_from_file_location("count_lines", ROOT / "benchmarks" / "count_lines.py")
    count_lines = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(count_lines)
    total = sum(count_lines.code_lines(p) for p in (ROOT / "kornia_ilum").rglob("*.py"))
    assert total <= 7100, total


def test_no_function_takes_more_than_five_positional_parameters() -> None:
    """Keyword-only arguments after the first one or two wherever a function takes more than four: in the library,
    the lab and the plugins, no function takes more than 5 positional parameters (``self``/``cls`` aside)."""
    over = []
    for module, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                names = [a.arg for a in node.args.posonlyargs + node.args.args]
                positional = [n for n in names if n not in ("self", "cls")]
                if len(positional) > 5:
                    over.append(f"{module}.{node.name} ({len(positional)})")
    assert over == []


# ------------------------------------------------------------------------------------------ conventions page
def _shared_spec() -> Path | None:
    candidates = [SHARED_DATA.parent / ("SPEC" + ".md"), ROOT.parent / "shared" / ("SPEC" + ".md")]
    return next((c for c in candidates if c.is_file()), None)


def _words(text: str) -> list[str]:
    return re.findall(r"[a-z]+|\d+(?:\.\d+)?", text.lower())


def _markdown_prose(text: str) -> list[str]:
    """The words of a Markdown text from its first section on, code spans (the formulas) left out."""
    return _words(re.sub(r"`[^`]*`", " ", text[text.index("\n## "):]))


def _rst_prose(text: str) -> list[str]:
    """The words of the reStructuredText page from its first section on, formulas, labels, figures and
    section underlines left out."""
    text = text[text.index("\nFrames\n"):]
    text = re.sub(r"^( *)\.\. (math|figure)::.*\n(?:\1 +.*\n|[ \t]*\n)*", "\n", text, flags=re.M)
    text = re.sub(r"^\.\. _[\w-]+:\n", "", text, flags=re.M)
    text = re.sub(r"^[-=~^]{3,}$", "", text, flags=re.M)
    text = re.sub(r":\w+:`[^`]*`|``[^`]*``", " ", text)
    return _words(text)


def test_conventions_page_says_what_the_shared_conventions_say() -> None:
    spec = _shared_spec()
    if spec is None:
        pytest.skip("the shared conventions file is not beside this checkout")
    page = (ROOT / "docs" / "conventions.rst").read_text()
    expected, actual = _markdown_prose(spec.read_text()), _rst_prose(page)
    diff = list(difflib.unified_diff(expected, actual, "shared", "docs/conventions.rst", lineterm="", n=4))
    assert expected == actual, "\n".join(diff[:60])
