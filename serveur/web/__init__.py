"""The web UI: its pages, scripts and styles (``site/``) and the code that serves them.

Owns :mod:`~serveur.web.static` (every file of ``site/`` read once into memory and answered
by path, with the security headers) and the files of ``site/`` themselves: the staff console,
a robot's screen and a table's screen. They talk to the server only over ``/ws``.

May import: nothing of serveur but serveur.errors.
"""

__all__: list[str] = []
