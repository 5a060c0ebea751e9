"""Robot conditions: what a real robot's conditions do between the world and the method.

* :mod:`~benchmark.conditions.pose_error`: the poses the method receives (noise, drift, loop closures);
* :mod:`~benchmark.conditions.label_noise`: a share of views relabelled (classifier noise);
* :mod:`~benchmark.conditions.exploration`: viewpoints as an exploring robot takes them (frontier
  exploration with a budget, a random walk), building its map as it goes;
* :mod:`~benchmark.conditions.coverage`: how much of the house the views saw.

The map a robot builds from its laser lives on the world side (:mod:`envs.maps.scan`); each
condition is a stage option chosen in ``conf/`` (``pose_error``, ``label_noise``, ``viewpoints``,
``mapping``), and ``conf/corruption`` sets them at severities. docs/robot-conditions.md says what
each models and leaves out, with units.
"""
