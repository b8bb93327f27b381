"""``serveur hq``: the chain's centre (issue 34; docs/chain.md).

Owns :mod:`~serveur.hq.store` (the centre's database: every site's events exactly once, its
sites and their liveness, its own accounts), :mod:`~serveur.hq.consumer` (the broker's
streams into it, with :mod:`serveur.chain.ledger`'s rules), :mod:`~serveur.hq.views` (pure:
what the dashboard shows of a site, with the site's own statistics code),
:mod:`~serveur.hq.dashboard` (its HTTP routes) and :mod:`~serveur.hq.cli` (the subcommand).
A site never imports it.

May import: serveur.chain, serveur.clock, serveur.domain, serveur.errors, serveur.mqtt.session,
serveur.security.auth, serveur.stats, serveur.store, serveur.till.intake, serveur.web.static.
"""

__all__: list[str] = []
