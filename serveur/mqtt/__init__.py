"""The restaurant's MQTT broker, where it has one: call buttons that publish instead of
requesting an address (:mod:`~serveur.mqtt.calls`); and the reconnect loop every MQTT client
of serveur shares (:mod:`~serveur.mqtt.session`, also the chain's: :mod:`serveur.chain`).

aiomqtt (over paho-mqtt) is imported only when a broker is configured (``serveur serve
--mqtt``): a site without one needs neither.

May import: serveur.core, serveur.domain, serveur.errors.
"""

__all__: list[str] = []
