"""Tests of serveur.robots."""
