"""Pose tracking: the silhouette likelihood (declares) and the particle filters (infer)."""
