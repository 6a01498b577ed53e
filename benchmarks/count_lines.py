"""Lines of code of a package, docstrings, comments and blank lines aside: the size the issue-41 bar counts.

Run: ``python benchmarks/count_lines.py kornia_ilum plugins/lab/kornia_ilum_lab``

For each folder, the sum over its ``.py`` files of the lines that hold code: a line is left out when it is blank,
only a comment, or inside a docstring (the first string statement of a module, class or function).
"""

from __future__ import annotations

import ast
import io
import sys
import tokenize
from pathlib import Path


def code_lines(path: Path) -> int:
    """The lines of ``path`` that hold code (no blank, comment-only or docstring line)."""
    source = path.read_text(encoding="utf-8")
    doc = set()
    for node in ast.walk(ast.parse(source)):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body
                and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            doc.update(range(body[0].lineno, body[0].end_lineno + 1))
    lines = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
                            tokenize.ENDMARKER):
            lines.update(range(tok.start[0], tok.end[0] + 1))
    return len(lines - doc)


def main(argv: list[str] | None = None) -> None:
    for folder in (argv if argv is not None else sys.argv[1:]) or ["kornia_ilum"]:
        files = sorted(Path(folder).rglob("*.py"))
        print(f"{folder}: {sum(code_lines(p) for p in files)} lines of code in {len(files)} files")


if __name__ == "__main__":
    main()
