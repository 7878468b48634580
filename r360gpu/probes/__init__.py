"""Probes: semantic (prompted) and structural (prompt-free) mask predictors."""
