"""Tests of serveur.web."""
