"""The layout's numbers: private names used across modules, and functions over 100 lines of
code (their docstrings apart), in `src/stickslip` and `plugins`.

    python benchmarks/layout.py            # the counts
    python benchmarks/layout.py --list     # and each name and function

A private name (a leading underscore) used by another module is a reach into that module's
inside; the modules of a private package (`stickslip._inference`, ...) share the names
without an underscore, and a private *module* imported whole (`from .. import _rng`) is
the package's layout, not counted. Numerical kernels (functions traced by JAX: one
compiled program each) are listed apart.
"""

from __future__ import annotations

import argparse
import ast
import collections
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "stickslip"
# Modules whose long functions are compiled kernels (one traced program each).
KERNELS = {"_simulate/device.py", "_simulate/bridge.py", "_simulate/chain.py"}
OUTSIDE = {"np", "jnp", "jax", "warnings", "os", "sys", "threading", "eqx", "diffrax", "xr",
           "signal", "importlib", "multiprocessing", "concurrent", "collections", "functools",
           "io"}  # fmt: skip


def files() -> list[pathlib.Path]:
    return sorted(SRC.rglob("*.py")) + sorted((ROOT / "plugins").rglob("*.py"))


def private_uses() -> dict:
    """(module, name) -> the files that use that private name of another module."""
    modules = {p.stem for p in SRC.rglob("*.py")} | {p.name for p in SRC.rglob("*") if p.is_dir()}
    uses = collections.defaultdict(set)
    for path in files():
        tree = ast.parse(path.read_text())
        imported = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for alias in node.names:
                    name = alias.name
                    if name.startswith("_") and not name.startswith("__") and name not in modules:
                        uses[node.module or ".", name].add(path)
                    else:
                        imported[alias.asname or name] = node.module
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in imported and node.value.id not in OUTSIDE
                    and node.attr.startswith("_") and not node.attr.startswith("__")
                    and node.attr not in modules):  # fmt: skip
                uses[node.value.id, node.attr].add(path)
    return uses


def long_functions(limit: int = 100) -> list[tuple]:
    """(code lines, docstring lines, file, name, kernel?) of the functions past `limit`
    lines of code."""
    out = []
    for path in files():
        rel = path.relative_to(SRC).as_posix() if path.is_relative_to(SRC) else path.name
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                doc = 0
                if ast.get_docstring(node) is not None:
                    doc = node.body[0].end_lineno - node.body[0].lineno + 1
                if lines - doc > limit:
                    out.append((lines - doc, doc, rel, node.name, rel in KERNELS))
    return sorted(out, reverse=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--list", action="store_true", help="list the names and functions")
    args = parser.parse_args()
    uses = private_uses()
    pairs = sum(len(v) for v in uses.values())
    longs = long_functions()
    kernels = [f for f in longs if f[4]]
    print(f"private names used across modules: {len(uses)} ({pairs} uses)")
    print(f"functions over 100 lines of code: {len(longs) - len(kernels)} "
          f"(and {len(kernels)} compiled kernels)")  # fmt: skip
    if args.list:
        for (module, name), where in sorted(uses.items()):
            shown = ", ".join(sorted(p.relative_to(ROOT).as_posix() for p in where))
            print(f"  {module}.{name}: {shown}")
        for code, _doc, rel, name, kernel in longs:
            print(f"  {rel}:{name}: {code} lines of code{' (kernel)' if kernel else ''}")


if __name__ == "__main__":
    main()
