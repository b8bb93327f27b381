"""The web UI: its pages, scripts and styles (``site/``) and the code that serves them.

Owns :mod:`~serveur.web.static` (every file of ``site/`` read once into memory and answered
by path, with the security headers) and the files of ``site/`` themselves: the staff console,
a robot's screen and a table's screen. They talk to the server only over ``/ws``. One script
is made rather than read: the allowed-actions table, written from :mod:`serveur.status`.

May import: serveur.status (the pure status machine, for its allowed-actions table).
"""

__all__: list[str] = []
