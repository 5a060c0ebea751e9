"""Robot recordings in: ROS 1 ``.bag`` and ROS 2 bags (sqlite3, MCAP) read with ``rosbags``
(pure Python; the optional extra ``bags``), and the segmentation written back as a bag.

* :mod:`envs.bags.source`: open a bag (one line for a missing, truncated or unindexed file),
  list its topics, stream its messages;
* :mod:`envs.bags.occupancy`: ``nav_msgs/OccupancyGrid`` -> :class:`envs.maps.gridmap.GridMap`
  with the ROS origin, resolution and frame;
* :mod:`envs.bags.transforms`: a tf buffer (``/tf``, ``/tf_static``) and pose topics,
  interpolated at a stamp;
* :mod:`envs.bags.views`: per-view labels and images, subsampled by distance and turn;
* :mod:`envs.bags.read`: the whole read (map, poses, views) in two streaming passes;
* :mod:`envs.bags.write`: the segmented map and the rooms as ``visualization_msgs/MarkerArray``
  into a ROS 1 bag, a ROS 2 sqlite3 bag or an MCAP file.
"""
