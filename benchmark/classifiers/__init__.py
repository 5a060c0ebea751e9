"""Classifiers: N observations -> (N, C) class probabilities (see benchmark.interfaces)."""
