"""``slip-estimator bench``: throughput, latency and memory of the estimator on this machine.

Sections (``--only`` selects a comma-separated subset; every duration is an argument so a smoke
test runs the whole bench in seconds):

core     IMU steps/s of the full :class:`~slip_estimator.core.estimator.SlipEstimator` on a
         simulated drive (records built before timing, best of ``--repeats``), with the default
         ``covariance_decimation`` and the reference path (``covariance_decimation=1``).
replay   :func:`slip_estimator.replay.replay_bag` on a simulated 250 Hz bag (and the real s5t1
         Pathfinder log when ``../shared/data/pathfinder/s5t1.mat`` exists), with the split
         bag read (read + decode the IMU + reorder) / estimation (adapter: wheel decoding, core,
         output messages, NaN guard) / bag write (serialize + write) that replay_bag itself
         measures (best of ``--replay-repeats`` replays); then the whole process
         (``slip-estimator replay`` in a subprocess: start-up and imports included), wall and
         CPU time.
live     the real node (``python -m slip_estimator.ros.node``) in a subprocess, fed over DDS by
         a publisher in another subprocess (IMU at each of ``--live-imu-rates``, default 250
         and 1000 Hz, JointState 10 Hz, wall-clock stamps);
         messages received vs sent, IMU callback latency (the node's ``callback_*_ms``
         diagnostics), end-to-end latency IMU stamp -> ``/slip_estimator/odometry`` arrival,
         node CPU (``/proc/<pid>/stat`` utime+stime).
memory   RSS of a subprocess pushing a chained simulated drive (default one hour at 250 Hz)
         through the core at full speed, sampled every ``--memory-sample-s`` of data time.
scaling  core cost vs IMU rate (50..1000 Hz, same drive simulated at that rate) and vs log
         length.

``--baseline DIR`` (a source tree of an earlier version: ``git worktree add DIR REV`` or
``git archive REV | tar -x -C DIR``) measures that version's node and whole replay process
right after this tree's, in the same run, and compares its replay outputs with this tree's
(:mod:`slip_estimator.bench.identical`). ``--json FILE`` writes every figure. Only the standard
library, numpy and the package are used
(CPU and memory from ``/proc``).

Modules: ``cli`` (the command), ``throughput`` (core, replay, scaling), ``live`` (the only
rclpy module), ``memory``, ``tables`` (printing), ``machine`` (/proc facts); ``soak`` (an hour
of simulated driving with seeded faults, ``python -m slip_estimator.bench.soak``) and
``faults`` (the fault mutators and measurements it shares with the fault-injection tests);
``identical`` (two replay outputs compared field by field, bit for bit:
``python -m slip_estimator.bench.identical BEFORE AFTER``).
"""
