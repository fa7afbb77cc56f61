"""The code's structure: plugins and examples use only public names, and the package has no
import circles.

The import graph is read from the source with `ast` (every `import` and `from ... import`,
those inside functions included): module A depends on module B when A imports B or a name
from B. A circle is a strongly connected component of that graph with more than one module.
"""

from __future__ import annotations

import ast
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "stickslip"
PYTHON_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def _private_uses(tree: ast.AST) -> list[str]:
    """Imports of a private stickslip module (`stickslip._x`, `stickslip.y._z`) or of a
    private name from stickslip (`from stickslip import _x`)."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "stickslip" and any(p.startswith("_") for p in parts[1:]):
                found.append(name)
    return found


def _third_party_sources():
    """What a third-party author writes: the plugins, the examples and the code blocks of
    docs/extending.md."""
    for path in sorted([*(ROOT / "plugins").rglob("*.py"), *(ROOT / "examples").rglob("*.py")]):
        yield str(path.relative_to(ROOT)), path.read_text()
    text = (ROOT / "docs" / "extending.md").read_text()
    for k, block in enumerate(PYTHON_BLOCK.findall(text)):
        yield f"docs/extending.md block {k}", block


def test_plugins_and_examples_use_only_public_names():
    sources = list(_third_party_sources())
    assert len(sources) > 10
    bad = {}
    for name, text in sources:
        uses = _private_uses(ast.parse(text))
        # attribute access on the package itself, e.g. `ss._rng` or `stickslip._compile`
        uses += re.findall(r"\b(?:ss|stickslip)\.(_[a-z]\w*)", text)
        if uses:
            bad[name] = uses
    assert not bad, bad


def test_the_checker_sees_private_imports():
    code = "\n".join(
        [
            "from stickslip._errors import check_real",
            "import stickslip._jax",
            "from stickslip import _rng",
        ]
    )
    assert _private_uses(ast.parse(code)) == [
        "stickslip._errors", "stickslip._errors.check_real", "stickslip._jax", "stickslip._rng",
    ]  # fmt: skip


def test_the_plugin_module_exports_what_it_names():
    import stickslip.plugin as plugin

    for name in plugin.__all__:
        assert getattr(plugin, name) is not None, name
    assert issubclass(plugin.ChainModel, plugin.FrictionModel)
    assert plugin.jnp.zeros(1).dtype == plugin.jnp.float64


def _modules() -> dict[str, pathlib.Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports (anywhere in its source)."""
    modules = _modules()
    graph = {name: set() for name in modules}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[: len(base) - (node.level - 1)]
                    base = ".".join(base + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                # `from pkg import sub` depends on the submodule only; any other name on the
                # module it comes from
                subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in modules]
                targets = subs + ([base] if len(subs) < len(node.names) else [])
            graph[name] |= {t for t in targets if t in modules and t != name}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_circles():
    graph = import_graph()
    assert len(graph) > 40 and "stickslip._simulate.loop" in graph["stickslip._simulate.driver"]
    assert circles(graph) == []


def test_the_circle_finder_finds_circles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert circles(graph) == [["a", "b", "c"]]
