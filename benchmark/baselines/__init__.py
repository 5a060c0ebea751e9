"""Baselines: scoring external methods' output maps, and geometric segmenters."""
