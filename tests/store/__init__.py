"""Tests of serveur.store."""
