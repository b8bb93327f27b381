"""Check serveur's package layout: no import circles, a short top level, declared dependencies.

Run from the project root (``.ci/run`` does, and ``tests/test_layout.py`` runs it too)::

    python3 tools/check_layout.py

Every ``import`` of a ``serveur`` module counts — at module level, inside functions and under
``if TYPE_CHECKING:`` alike — because a circle hidden in a function is still a circle in the
design. Importing ``serveur.a.b`` also imports the packages ``serveur`` and ``serveur.a``
(their ``__init__``), so those edges count too. The rules:

1. no circle of imports among serveur's modules;
2. at most ``MAX_TOP`` modules directly under ``serveur/`` (``__init__`` included);
3. every subpackage's ``__init__`` has a docstring with a ``May import:`` line, and every
   module inside it imports, outside the subpackage, only what that line names (a module
   or a package prefix; ``serveur.errors`` is always allowed);
4. the pure rules (``PURE``) import, directly or not, only pure serveur modules and no I/O
   library;
5. no circle of imports among the web UI's scripts (``serveur/web/site/**/*.js``, and the
   chain's dashboard's ``serveur/web/hq/**/*.js``): every static
   ``import … from "./x.js"`` / ``export … from "./x.js"`` / ``import "./x.js"`` and every
   dynamic ``import("./x.js")`` with a relative path (or one from the site's root, "/js/x.js")
   counts; comments and other strings do not.
   A browser runs a circle of ES modules, but in an order that depends on which module a page
   loads first, so a name read at load time can be unset in one page and fine in another.

Exit status 0 when all hold; otherwise each broken rule is printed and the status is 1.
"""

from __future__ import annotations

import ast
import re
import sys
from collections.abc import Iterable
from pathlib import Path

MAX_TOP = 12
# What the design card calls the pure rules: the protocol, the status machine, scheduling.
PURE = ("serveur.protocol", "serveur.status", "serveur.scheduler")
# Modules the pure rules may lean on (themselves pure: no sockets, no files, no database).
PURE_ALLOWED = ("serveur.domain", "serveur.errors", "serveur.wire", *PURE)
#: The web pages' roots under serveur/web: the site's and the chain centre's dashboard.
WEB_ROOTS = ("site", "hq")
IO_LIBRARIES = ("websockets", "aiosqlite", "asyncmy", "sqlite3", "socket", "ssl", "http")
ALWAYS_ALLOWED = ("serveur.errors",)


def module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def discover(root: Path) -> dict[str, Path]:
    return {module_name(root, p): p for p in sorted(root.rglob("*.py"))}


def _ancestors(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def imports(name: str, path: Path, modules: dict[str, Path]) -> tuple[set[str], set[str]]:
    """(serveur modules, third-party top-level names) that ``name`` imports anywhere."""
    tree = ast.parse(path.read_text("utf-8"), str(path))
    is_package = path.name == "__init__.py"
    own: set[str] = set()
    foreign: set[str] = set()
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base if is_package else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [mod]
            # ``from pkg import sub`` imports the submodule pkg.sub
            targets += [f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in modules]
        for t in targets:
            if t == "serveur" or t.startswith("serveur."):
                while t not in modules and "." in t:
                    t = t.rsplit(".", 1)[0]
                own.add(t)
                own.update(a for a in _ancestors(t) if a in modules)
            elif t:
                foreign.add(t.split(".")[0])
    own.discard(name)
    return own, foreign


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work: list[tuple[str, Iterable[str]]] = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    comp: list[str] = []
                    while True:
                        m = stack.pop()
                        on_stack.discard(m)
                        comp.append(m)
                        if m == node:
                            break
                    if len(comp) > 1:
                        found.append(sorted(comp))
    return found


def _allowed(target: str, prefixes: Iterable[str]) -> bool:
    """``target`` is one of ``prefixes``, inside one, or a package on the way to one.

    Importing ``serveur.store.base`` runs ``serveur/store/__init__.py`` first, so allowing a
    module allows the packages above it (their ``__init__`` imports nothing of serveur here).
    """
    return any(
        target == p or target.startswith(p + ".") or p.startswith(target + ".") for p in prefixes
    )


_MAY_IMPORT = re.compile(r"^May import:(.*?)(?:\n\s*\n|\Z)", re.M | re.S)


def declared(path: Path) -> list[str] | None:
    doc = ast.get_docstring(ast.parse(path.read_text("utf-8"))) or ""
    m = _MAY_IMPORT.search(doc)
    if m is None:
        return None
    names = re.findall(r"serveur(?:\.\w+)*", m.group(1))
    return names


def check(root: Path) -> list[str]:
    modules = discover(root)
    graph: dict[str, set[str]] = {}
    foreign: dict[str, set[str]] = {}
    for name, path in modules.items():
        graph[name], foreign[name] = imports(name, path, modules)
    problems: list[str] = []
    for comp in cycles(graph):
        problems.append("import circle: " + " <-> ".join(comp))
    top = sorted(p.name for p in root.glob("*.py"))
    if len(top) > MAX_TOP:
        problems.append(f"{len(top)} modules directly under serveur/ (at most {MAX_TOP}): {top}")
    packages = [n for n, p in modules.items() if p.name == "__init__.py" and n != "serveur"]
    for pkg in packages:
        allowed = declared(modules[pkg])
        if allowed is None:
            problems.append(f"{pkg}: its docstring has no 'May import:' line")
            continue
        outer = pkg.rsplit(".", 1)[0]
        for name in modules:
            if not (name == pkg or name.startswith(pkg + ".")):
                continue
            for target in sorted(graph[name]):
                inside = target == pkg or target.startswith(pkg + ".")
                if inside or target in _ancestors(pkg) or target == outer:
                    continue
                if not _allowed(target, [*allowed, *ALWAYS_ALLOWED]):
                    problems.append(f"{name} imports {target}, which {pkg} does not declare")
    for pure in (p for p in PURE if p in modules):
        seen: set[str] = set()
        todo = [pure]
        while todo:
            m = todo.pop()
            if m in seen:
                continue
            seen.add(m)
            if m != "serveur" and not _allowed(m, PURE_ALLOWED):
                problems.append(f"{pure} (pure) reaches {m}, which is not pure")
                continue
            bad = foreign[m] & set(IO_LIBRARIES)
            if bad:
                problems.append(f"{pure} (pure) reaches {m}, which imports {sorted(bad)}")
            todo.extend(graph[m])
    for pages in WEB_ROOTS:  # each served from its own root: a circle stays inside one
        site = root / "web" / pages
        if site.is_dir():
            problems += check_js(site)
    return problems


# --- the web UI's scripts ---------------------------------------------------------------------

_JS_STATIC = re.compile(
    r"""(?:^|[;}])\s*(?:import|export)\b[^;"'`]*?\bfrom\s*(["'])([^"'\n]+)\1"""
    r"""|(?:^|[;}])\s*import\s*(["'])([^"'\n]+)\3""",
    re.M,
)
_JS_DYNAMIC = re.compile(r"""\bimport\s*\(\s*(["'])([^"'\n]+)\1\s*\)""")


def js_code(text: str) -> str:
    """``text`` with its comments blanked (strings kept), so a commented-out import is no edge.

    A small scanner: string and template literals are skipped whole (an import path is one), a
    ``//`` or ``/* */`` outside them is blanked. Regular-expression literals are not recognised;
    the site's scripts hold none with a quote or a comment marker in it.
    """
    out: list[str] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in "\"'`":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(text[i : j + 1])
            i = j + 1
        elif text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * text.count("\n", i, j))  # line numbers kept
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def js_imports(text: str) -> list[str]:
    """The module paths a script imports (static and dynamic), as written, in order."""
    code = js_code(text)
    found = [m.group(2) or m.group(4) for m in _JS_STATIC.finditer(code)]
    found += [m.group(2) for m in _JS_DYNAMIC.finditer(code)]
    return found


def js_graph(site: Path) -> dict[str, set[str]]:
    """Script -> the scripts it imports by a relative or site-rooted path, named from ``site``
    ("js/ui.js").

    A path that leaves ``site`` or names no file (``js/status-table.js`` is made by static.py
    when the server starts) is a leaf: it imports nothing here.
    """
    base = site.resolve()
    graph: dict[str, set[str]] = {}
    for path in sorted(site.rglob("*.js")):
        name = path.relative_to(site).as_posix()
        edges = graph.setdefault(name, set())
        for spec in js_imports(path.read_text("utf-8")):
            if spec.startswith(("./", "../")):
                target = (path.parent / spec).resolve()
            elif spec.startswith("/") and not spec.startswith("//"):
                target = (site / spec[1:]).resolve()  # from the site's root, as served
            else:
                continue  # a bare name or a URL: not one of ours
            if target.is_relative_to(base):
                edges.add(target.relative_to(base).as_posix())
    return graph


def _circle_through(graph: dict[str, set[str]], comp: list[str]) -> list[str]:
    """One shortest circle inside the tangle ``comp``, from its first module back to it."""
    inside = set(comp)
    start = comp[0]
    came: dict[str, str] = {}
    todo = [start]
    while todo:
        nxt: list[str] = []
        for m in todo:
            for child in sorted(graph.get(m, ())):
                if child == start:
                    path = [m]
                    while path[-1] != start:
                        path.append(came[path[-1]])
                    return [*reversed(path), start]
                if child in inside and child not in came:
                    came[child] = m
                    nxt.append(child)
        todo = nxt
    return [start, start]  # unreachable for a strongly connected comp


def check_js(site: Path) -> list[str]:
    """Rule 5: the scripts under ``site`` import no circle; each found is named."""
    graph = js_graph(site)
    problems: list[str] = []
    for comp in cycles(graph):
        circle = _circle_through(graph, comp)
        # A tangle wider than the one circle named: its other modules are said too.
        more = f" (the tangle: {', '.join(comp)})" if len(comp) > len(circle) - 1 else ""
        problems.append(f"JS import circle: {' -> '.join(circle)}{more}")
    for name in sorted(graph):
        if name in graph[name]:
            problems.append(f"JS import circle: {name} -> {name}")
    return problems


def main() -> int:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent
    root = root / "serveur" if (root / "serveur").is_dir() else root
    problems = check(root)
    for p in problems:
        print(p)
    modules = discover(root)
    scripts = sum(1 for pages in WEB_ROOTS for _ in (root / "web" / pages).rglob("*.js"))
    print(
        f"{len(modules)} modules, {sum(1 for p in root.glob('*.py'))} at the top, "
        f"{scripts} scripts, {len(problems)} problem(s)"
    )
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
