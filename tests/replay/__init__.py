"""Tests of serveur.replay."""
