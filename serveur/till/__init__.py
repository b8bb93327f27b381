"""The restaurant's till (point of sale): its kitchen tickets read as orders.

:mod:`~serveur.till.escpos` reads a kitchen printer's job back as the text it prints (pure),
:mod:`~serveur.till.pattern` the owner's ticket pattern: which line is the table, which lines
are dishes (pure), :mod:`~serveur.till.names` matches the till's item names to the menu (pure),
:mod:`~serveur.till.tap` listens as a network printer and forwards each job to the real one,
and :mod:`~serveur.till.intake` is the HTTP order-intake API for integrations (thin shells:
what a job or a request becomes is the core's ticket desk's, handed in).

May import: serveur.errors, serveur.clock.
"""

__all__: list[str] = []
