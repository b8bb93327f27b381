"""Tests of serveur.maps."""
