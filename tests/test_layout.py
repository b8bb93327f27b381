"""The package layout holds: no import circle (Python modules and the web UI's scripts), a short
top level, declared imports, a wheel that carries every module, migration and page.

``tools/check_layout.py`` is the rule book (``.ci/run`` runs it too); these tests run it on
serveur itself and on small made-up trees, so a checker that stopped seeing circles fails here.
"""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("check_layout", ROOT / "tools" / "check_layout.py")
assert _spec is not None and _spec.loader is not None
check_layout = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(check_layout)


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    root = tmp_path / "serveur"
    for name, text in {"__init__.py": '"""root."""\n', **files}.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_serveur_holds_every_rule() -> None:
    assert check_layout.check(ROOT / "serveur") == []


def test_the_command_exits_zero_on_serveur() -> None:
    out = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "check_layout.py")],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 problem(s)" in out.stdout


def test_a_circle_through_a_lazy_import_is_found(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        {
            "a.py": "from serveur.b import x\n",
            "b.py": "def x():\n    from serveur import a\n",
        },
    )
    problems = check_layout.check(root)
    assert any("import circle" in p and "serveur.a" in p and "serveur.b" in p for p in problems)


def test_a_circle_under_type_checking_and_relative_imports_is_found(tmp_path: Path) -> None:
    doc = '"""p.\n\nMay import: serveur.errors.\n"""\n'
    root = _tree(
        tmp_path,
        {
            "pkg/__init__.py": doc,
            "pkg/one.py": "from .two import y\n",
            "pkg/two.py": (
                "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .one import z\n"
            ),
        },
    )
    assert any("import circle" in p for p in check_layout.check(root))


def test_an_undeclared_import_and_a_missing_declaration_are_found(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        {
            "domain.py": "",
            "pkg/__init__.py": '"""p.\n\nMay import: serveur.domain.\n"""\n',
            "pkg/m.py": "from serveur import other\n",
            "other.py": "",
            "bare/__init__.py": '"""No declaration."""\n',
        },
    )
    problems = check_layout.check(root)
    assert "serveur.pkg.m imports serveur.other, which serveur.pkg does not declare" in problems
    assert "serveur.bare: its docstring has no 'May import:' line" in problems


def test_a_pure_rule_that_reaches_io_is_found(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        {
            "status.py": "from serveur import store\n",
            "store.py": "import aiosqlite\n",
            "scheduler.py": "import websockets\n",
        },
    )
    problems = check_layout.check(root)
    assert "serveur.status (pure) reaches serveur.store, which is not pure" in problems
    assert any(p.startswith("serveur.scheduler (pure)") and "websockets" in p for p in problems)


def test_a_long_top_level_is_found(tmp_path: Path) -> None:
    root = _tree(tmp_path, {f"m{i}.py": "" for i in range(check_layout.MAX_TOP)})
    assert any("modules directly under serveur/" in p for p in check_layout.check(root))


def _scripts(tmp_path: Path, files: dict[str, str]) -> Path:
    site = tmp_path / "serveur" / "web" / "site"
    for name, text in files.items():
        path = site / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return site


def test_the_web_scripts_import_no_circle() -> None:
    site = ROOT / "serveur" / "web" / "site"
    graph = check_layout.js_graph(site)
    # The checker reads the real imports (a checker that saw none would find no circle either).
    assert "js/staff/maptools.js" in graph["js/staff/main.js"]
    assert {"js/staff/forms.js", "js/staff/leases.js"} <= graph["js/staff/maptools.js"]
    assert "js/staff/maptools.js" not in graph["js/staff/restaurant/zones.js"]
    assert sum(len(e) for e in graph.values()) > 100
    assert check_layout.check_js(site) == []


def test_a_js_circle_is_found_and_named(tmp_path: Path) -> None:
    site = _scripts(
        tmp_path,
        {
            "js/a.js": 'import { b } from "./sub/b.js";\nexport const a = 1;\n',
            # A re-export, over several lines, is an import too.
            "js/sub/b.js": 'export {\n  c,\n} from "../c.js";\nexport const b = 2;\n',
            # A dynamic import from the site's root closes the circle a -> b -> c -> a.
            "js/c.js": 'export const c = 3;\nexport const later = () => import("/js/a.js");\n',
        },
    )
    problems = check_layout.check_js(site)
    assert problems == ["JS import circle: js/a.js -> js/sub/b.js -> js/c.js -> js/a.js"]
    # And through the whole check, on a serveur tree that holds the site.
    (tmp_path / "serveur" / "__init__.py").write_text('"""root."""\n')
    assert problems[0] in check_layout.check(tmp_path / "serveur")


def test_comments_strings_and_bare_names_are_no_js_import(tmp_path: Path) -> None:
    site = _scripts(
        tmp_path,
        {
            "js/a.js": (
                'import "./b.js";\n'
                "// import { a } from './a.js';\n"
                '/* import("./a.js") */\n'
                "export const s = 'import x from \"./a.js\"';\n"
                'import { x } from "lib";\n'
            ),
            "js/b.js": '// once: import { a } from "./a.js";\nexport const url = "http://x/a.js";\n',
        },
    )
    graph = check_layout.js_graph(site)
    assert graph == {"js/a.js": {"js/b.js"}, "js/b.js": set()}
    assert check_layout.check_js(site) == []
    # A module importing itself is a circle too.
    (site / "js" / "b.js").write_text('import { b } from "./b.js";\nexport const b = 1;\n')
    assert check_layout.check_js(site) == ["JS import circle: js/b.js -> js/b.js"]


def test_tests_mirror_the_packages() -> None:
    # Python test packages (tests/node holds the roslibjs client the sim tests run under Node).
    tests = (ROOT / "tests").iterdir()
    folders = {p.name for p in tests if (p / "__init__.py").exists()}
    packages = {p.name for p in (ROOT / "serveur").iterdir() if (p / "__init__.py").exists()}
    assert folders <= packages, folders - packages


@pytest.mark.slow
def test_the_wheel_carries_every_module_migration_and_page(tmp_path: Path) -> None:
    # Built from a clean copy: setuptools reuses a build/ folder left in the source tree.
    src = tmp_path / "src"
    shutil.copytree(
        ROOT,
        src,
        ignore=shutil.ignore_patterns(".git", "build", "*.egg-info", "__pycache__", "*.db*"),
    )
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(tmp_path),
            str(src),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("serveur-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    source = ROOT / "serveur"
    wanted = {p.relative_to(ROOT).as_posix() for p in source.rglob("*.py")}
    wanted |= {p.relative_to(ROOT).as_posix() for p in (source / "web" / "site").rglob("*.*")}
    wanted |= {p.relative_to(ROOT).as_posix() for p in (source / "data").iterdir()}
    wanted |= {f"serveur/migrations/{p.name}" for p in (ROOT / "migrations").glob("*.sql")}
    assert wanted - names == set()
    assert any(n.startswith("serveur/migrations/001_") for n in names)
