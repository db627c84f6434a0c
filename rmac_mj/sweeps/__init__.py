"""Sweeps: TOML sweep files, their grid of ``reproduce`` runs, and their figures."""
