"""Maps: the occupancy grid (:class:`envs.maps.gridmap.GridMap`), houses rasterised into a
map + ground truth (:class:`envs.maps.scene.Scene`), readers and writers of label,
instance and ground-truth images, annotations, and pose conversions between frames."""
