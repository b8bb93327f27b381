"""The schema history: the numbered SQL files of ``migrations/``, read for one dialect.

The files live in the project's top-level ``migrations/`` folder, which the build ships inside
the package as :mod:`serveur.migrations` (``pyproject.toml``'s ``package-dir``), so a wheel
and a source checkout read the same files through :mod:`importlib.resources`. Both SQL
backends apply this history; neither owns it, so it lives beside them, not in either.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from importlib import resources

from serveur.errors import StoreError

__all__ = ["DIALECTS", "SITE_HISTORY", "Migration", "load_migrations"]

#: The SQL dialects a migration file may be written for.
DIALECTS = ("sqlite", "mariadb")

_MIGRATION_NAME = re.compile(r"^(\d{3,})_([a-z0-9_]+?)(?:\.(sqlite|mariadb))?\.sql$")


@dataclass(frozen=True, slots=True)
class Migration:
    """One step of the schema history, in the SQL of one dialect."""

    version: int
    name: str
    sql: str


#: The site's history; the chain's centre has its own (``serveur.migrations.hq``).
SITE_HISTORY = "serveur.migrations"


def load_migrations(dialect: str, package: str = SITE_HISTORY) -> list[Migration]:
    """The migration history for ``dialect``, oldest first, read from the package data
    ``package`` (the site's, or the centre's: same rules, another schema).

    Read with :mod:`importlib.resources` so that it works from a wheel as well as from the
    source tree. A version that exists for some dialect but has neither a file for
    ``dialect`` nor a dialect-neutral file is an error: the histories must not drift apart
    silently, or a database would miss a step depending on which backend created it.
    """
    if dialect not in DIALECTS:
        raise StoreError(f"unknown SQL dialect {dialect!r}", dialect=dialect)
    folder = resources.files(package)
    found: dict[int, dict[str | None, tuple[str, str]]] = {}
    names: dict[int, str] = {}
    for entry in folder.iterdir():
        m = _MIGRATION_NAME.match(entry.name)
        if m is None:
            continue
        version, name, file_dialect = int(m[1]), m[2], m[3]
        if names.setdefault(version, name) != name:
            raise StoreError(
                f"migration {version:03d} has two names: {names[version]!r} and {name!r}",
                version=version,
            )
        found.setdefault(version, {})[file_dialect] = (entry.name, entry.read_text("utf-8"))
    history: list[Migration] = []
    for version in sorted(found):
        files = found[version]
        if dialect in files and None in files:
            raise StoreError(
                f"migration {version:03d} has both a {dialect} and a dialect-neutral file",
                version=version,
            )
        chosen = files.get(dialect) or files.get(None)
        if chosen is None:
            raise StoreError(
                f"migration {version:03d} ({names[version]}) has no {dialect} file",
                version=version,
                dialect=dialect,
            )
        history.append(Migration(version, names[version], chosen[1]))
    return history
