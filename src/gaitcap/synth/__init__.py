"""Synthetic sessions rendered from real marker-based walks, with ground truth."""
