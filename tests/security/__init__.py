"""Tests of serveur.security."""
