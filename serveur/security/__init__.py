"""Who may do what, and proving who you are: roles, logins, tokens, the audit trail, TLS.

Owns :mod:`~serveur.security.auth` (the authorisation rules and hashing, pure),
:mod:`~serveur.security.sessions` (logging a connection in, revocation, the audit log),
:mod:`~serveur.security.accounts_cli` (``serveur user|token|audit``) and
:mod:`~serveur.security.tls` (the server's and the robot links' TLS contexts).
docs/security.md is its user's guide.

May import: serveur.clock, serveur.protocol, serveur.store.base, serveur.store.factory,
serveur.core.hub.
"""

__all__: list[str] = []
