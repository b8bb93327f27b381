"""Tests of serveur.sim."""
