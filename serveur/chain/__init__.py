"""The chain: many restaurants, one central view (issue 34; docs/chain.md).

Each site stays authoritative and offline-capable; what it records also goes, numbered, to
the chain's MQTT broker, and the centre (``serveur hq``, :mod:`serveur.hq`) stores it.

Owns :mod:`~serveur.chain.wire` (pure: topics, site names, the batch and control messages,
validated), :mod:`~serveur.chain.ledger` (pure: the centre's rule for a site's sequence —
take, ignore a duplicate, ask again for a gap — and a site's liveness, down once and up
once), :mod:`~serveur.chain.address` (the broker's URL, TLS and credentials) and
:mod:`~serveur.chain.shipper` (the site's task: the outbox to the broker, in order, QoS 1).

aiomqtt is imported only where a chain is configured.

May import: serveur.clock, serveur.domain, serveur.errors, serveur.mqtt.session, serveur.store.
"""

__all__: list[str] = []
