"""Tests of serveur.core."""
