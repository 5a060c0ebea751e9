"""The world: houses, occupancy maps, ground truth, renderers and simulators.

``envs`` never imports ``benchmark``.
"""
