"""The shape of the code (issue 30's tail): CLI size, long functions, complex blocks, mypy.

Counts, for the package:

- the CLI's lines (``balancer_id/cli/``) and each command's lines (decorators to end);
- functions over 80 *code lines* (lines holding code, not docstrings, comments or blanks,
  from the first decorator to the end);
- blocks of cyclomatic complexity >= 21 (radon's ranks D to F: functions, methods and the
  classes radon scores), when radon is installed;
- with ``--mypy``, mypy's error count over the whole package.

Usage: ``python benchmarks/code_shape.py [--mypy] [--list]`` (no randomness: it reads the
source as it is).
"""

from __future__ import annotations

import argparse
import ast
import io
import re
import subprocess
import sys
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "balancer_id"
LONG = 80
COMPLEX = 21
SKIP_TOKENS = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT,
               tokenize.DEDENT, tokenize.ENDMARKER, tokenize.ENCODING}


def _docstring_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(
                getattr(body[0], "value", None), ast.Constant
            ) and isinstance(body[0].value.value, str):
                lines.update(range(body[0].lineno, (body[0].end_lineno or body[0].lineno) + 1))
    return lines


def _code_lines(source: str, tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in SKIP_TOKENS:
            lines.update(range(tok.start[0], tok.end[0] + 1))
    return lines - _docstring_lines(tree)


def functions(path: Path) -> list[tuple[str, int, int]]:
    """(qualified name, first line, code lines) of every function in ``path``."""
    source = path.read_text(encoding="utf-8")
    tree = ast.parse(source)
    code = _code_lines(source, tree)
    out = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                first = min([d.lineno for d in child.decorator_list] + [child.lineno])
                span = range(first, (child.end_lineno or child.lineno) + 1)
                out.append((f"{prefix}{child.name}", first, len(code.intersection(span))))
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(tree, "")
    return out


def cli_shape() -> tuple[int, dict[str, int]]:
    """Lines of ``balancer_id/cli/`` and lines of each command (decorator to end)."""
    total = sum(len(p.read_text().splitlines()) for p in (PACKAGE / "cli").glob("*.py"))
    commands: dict[str, int] = {}
    for path in (PACKAGE / "cli").glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and any(
                "command" in ast.unparse(d) for d in node.decorator_list
            ):
                first = min(d.lineno for d in node.decorator_list)
                commands[node.name] = (node.end_lineno or node.lineno) - first + 1
    return total, commands


def complex_blocks() -> list[tuple[str, int]] | None:
    """(where, complexity) of every radon block of complexity >= 21, or None without radon."""
    try:
        from radon.complexity import cc_visit
    except ImportError:
        return None
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for block in cc_visit(path.read_text(encoding="utf-8")):
            if block.complexity >= COMPLEX:
                out.append((f"{path.relative_to(ROOT)}:{block.lineno} {block.name}",
                            block.complexity))
    return out


def mypy_errors() -> int:
    """mypy's error count over the whole package (as CI runs it)."""
    run = subprocess.run(
        [sys.executable, "-m", "mypy", "balancer_id", "--ignore-missing-imports",
         "--follow-imports=silent"], cwd=ROOT, capture_output=True, text=True, check=False,
    )
    found = re.search(r"Found (\d+) errors?", run.stdout)
    return int(found.group(1)) if found else 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mypy", action="store_true", help="also count mypy's errors")
    parser.add_argument("--list", action="store_true", help="list the long and complex ones")
    args = parser.parse_args()
    total, commands = cli_shape()
    print(f"CLI lines: {total}; commands: {len(commands)}; longest command: "
          f"{max(commands.values())} lines")
    for name, n in sorted(commands.items(), key=lambda kv: -kv[1]):
        print(f"  {name}: {n}")
    long = [(f"{p.relative_to(ROOT)}:{line} {name}", n)
            for p in sorted(PACKAGE.rglob("*.py")) for name, line, n in functions(p) if n > LONG]
    print(f"functions over {LONG} code lines: {len(long)}")
    if args.list:
        for where, n in sorted(long, key=lambda x: -x[1]):
            print(f"  {n:4d} {where}")
    blocks = complex_blocks()
    if blocks is None:
        print("blocks of CC >= 21: radon not installed")
    else:
        print(f"blocks of CC >= {COMPLEX}: {len(blocks)}")
        if args.list:
            for where, n in sorted(blocks, key=lambda x: -x[1]):
                print(f"  {n:4d} {where}")
    if args.mypy:
        print(f"mypy errors over balancer_id/: {mypy_errors()}")


if __name__ == "__main__":
    main()
