"""serveur: fleet server for restaurant waiter robots, with a rosbridge v2 robot simulator."""

__all__ = ["__version__"]

__version__ = "0.1.0"
