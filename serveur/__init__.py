"""serveur: fleet server for restaurant waiter robots (orders, trips, rosbridge v2 robot links, simulator)."""

__all__ = ["__version__"]

__version__ = "0.1.0"
