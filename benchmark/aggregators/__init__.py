"""Aggregators: views + class probabilities -> a label map (see benchmark.interfaces)."""
