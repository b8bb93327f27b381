"""The restaurant's MQTT broker, where it has one: call buttons that publish instead of
requesting an address (:mod:`~serveur.mqtt.calls`).

aiomqtt (over paho-mqtt) is imported only when a broker is configured (``serveur serve
--mqtt``): a site without one needs neither.

May import: serveur.core, serveur.domain, serveur.errors.
"""

__all__: list[str] = []
