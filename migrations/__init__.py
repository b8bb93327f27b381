"""The schema history: numbered SQL files, one per dialect (``NNN_name.sqlite.sql``,
``NNN_name.mariadb.sql``) or shared (``NNN_name.sql``).

Shipped inside the package as ``serveur.migrations`` (``pyproject.toml``); read by
:mod:`serveur.store.migrations`. Never edit a released file: add the next number.
"""
