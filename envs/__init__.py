"""The world a robot segments, in packages by role (``envs`` never imports ``benchmark``):

* :mod:`envs.world`: the house schema and its validation, the asset database, room types
  and classes;
* :mod:`envs.maps`: the occupancy grid, rasterisation of houses into map + ground truth,
  map/label/ground-truth readers and writers, annotations, pose conversions;
* :mod:`envs.render`: observations (the renderer contract), ray casting, the floorplan,
  AI2-THOR and Habitat renderers, the render cache;
* :mod:`envs.datasets`: the environment contract and the sets of houses (ProcTHOR,
  ArchitecTHOR, generated houses).
"""
