"""Evaluation: learning-curve metrics, statistics across experiments, the report people read."""
