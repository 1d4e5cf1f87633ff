"""``slip-estimator setup BAG``: the parameters of a robot from one of its logs.

Parts, in the order they run (compute, result, render):

* :mod:`.scan` reads the bag (the only ROS part): the input topics by type, their rates, gaps
  and stamps, and the plain series of :mod:`.signals`;
* :mod:`.mounting` and :mod:`.measure` measure on those series (numpy and the core only): the
  IMU's gravity, units, clipping and mounting; noise and bias at rest, the wheel lag, the
  effective track, the wheel radius ratio, the start (:mod:`.heading`);
* :mod:`.decide` turns declared parameters and measured figures into the parameters to write,
  each with its source, and the problems and checks of the report;
* :mod:`.render` writes the commented params file and the one-screen report; :mod:`.cli` is
  the command.
"""
