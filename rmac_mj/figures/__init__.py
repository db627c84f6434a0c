"""Figures drawn from saved results and snapshots (the paper's Figs. 2-4, performance profiles)."""
