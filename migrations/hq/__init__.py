"""The chain centre's schema history (``serveur hq``, issue 34): numbered SQL files, read by
:mod:`serveur.store.migrations` exactly as the site's are, applied to the centre's own
database (never a site's)."""
