"""Where the site's records used to live, before the store was split into parts (issue 27):
the names callers import from here, kept importable. The audit search is
:mod:`serveur.store.accounts`'; waypoints' dependents are :mod:`serveur.store.waypoints`'.
"""

from __future__ import annotations

from serveur.store.accounts import AuditQuery
from serveur.store.waypoints import Dependents

__all__ = ["AuditQuery", "Dependents"]
