"""serveur's tests: one folder per package of serveur/, the top-level modules' tests here."""
