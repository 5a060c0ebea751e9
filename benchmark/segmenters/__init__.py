"""Geometric segmenters (the ``segmenter`` config group): occupancy map -> room instances,
with no classes. One module per option: morphological, distance, voronoi."""
