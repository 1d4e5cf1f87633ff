"""The slip model: which part of a wheel/IMU forward-speed discrepancy is slip, and which is
INS error, and what the rim speed may therefore tell the filter (standard library only).

What it assumes
---------------
* **Slip is piecewise constant.** A rover's motor controllers hold the commanded wheel rate:
  in soft ground the wheels keep turning and the body slows, downhill the body runs ahead, and
  a terrain change can spin the wheels up at an unchanged body speed. Either way the free
  residual ``v_ins - g(s_hold) r omega`` steps by ``r omega * delta_s`` within 0.5-3 s and
  stays there.
* **INS error is a slow random walk** (vibration, tilt wander through the gyro, biases), whose
  spread the step test learns online, never below what the filter's own covariance predicts
  its free INS drifts over the same span (``ErrorStateFilter.forward_reading_var_mps2``);
  **wheel noise is white**, and the rim speed's age within one encoder sample is part of its
  error at starts and stops.
* **A slip change settles** within seconds: a body-side reading still moving when its
  measurement times out is INS drift, and the hold stays; so is a run of same-direction
  body-side readings, each alarm firing as soon as the step test could after the last hold,
  unless together they beat the drift (growing with the span) of their whole span.
* **An INS too coarse to place a slip within the low class** (the filter's 1-s prediction
  beyond 15 % of the rim speed: a consumer IMU) resolves only what beats its drift: a
  body-side change must beat twice its predicted drift over the span it integrated, a
  wheel-side change the wheel/INS consistency noise, and a start from rest whose speed has
  that variance takes the wheels' speed as the ground's.
* **Absolute slip is anchored at rest** (ZUPT): each change is measured from the held slip
  before it, so errors chain until the next stop or a return to the ground's baseline.
* A run-ahead needs a downhill pull and lasts as long as the grade: where the ground ahead
  levels out the body is back on the ground's slip; the same ground on another slope slips
  differently.

Where it fails (measured; docs/limits.md, docs/status.md, docs/sim-vs-real.md)
------------------------------------------------------------------------------
* A body-side change is the IMU's to see: on the real test17run IMU an oracle with perfect
  timing keeps the class of injected body-side levels in only 59-83 % of onsets.
* A slip changing over tens of seconds is absorbed as INS drift; a change below
  ``slip_change_fraction`` of the rim speed is not seen; turns raise the thresholds; a
  wheel-radius error is a constant slip.
* False alarms (medium or worse where the ground does not slip, share of moving time): real
  test17run 0.2 %, s5t1 0.7 % as recorded; 0.9 % on the simulated 30-Hz consumer robot
  with the vibrating grade; 8.0 % on the plain consumer robot with slip patches (4 seeds: a
  wrong hold after a stop, single readings during measurements). On a consumer IMU
  body-side slip is below what the IMU resolves: the slip model then holds the wheels'
  speed, and the published odometry falls back to wheels + gyro (``core.odometry_guard``).

Its parts, in the order a wheel sample meets them
-------------------------------------------------
* :mod:`.wheel_aid` -- what a wheel sample may tell the filter (the model, a recovery
  re-anchor, wheels that just stopped);
* :mod:`.model` -- the model itself (modes REST / MEASURE / TRACK): it owns the parts below,
  hands them the sample (:mod:`.records`) and applies what they return;
* :mod:`.stop_clock` -- when still wheels are a stop, and its zero-speed aid;
* :mod:`.rim_memory` -- the rim speeds it remembers (steady, how far they moved, when);
* :mod:`.measurement` -- one slip measurement while the INS runs free;
* :mod:`.settling` -- the slip a finished measurement settles on;
* :mod:`.chain` -- what a measured slip is held as (baseline, false alarm, chain spread);
* :mod:`.run_ahead` -- when a body can run ahead of its wheels;
* :mod:`.wheel_side` -- wheel-side changes (the rim moved, the body did not follow);
* :mod:`.body_side` -- body-side changes (an alarm of the step test, its continuity anchor);
* :mod:`.step_test` -- the multi-scale step test on the free residual;
* :mod:`.thresholds` -- the change thresholds;
* :mod:`.aided_record` -- the recent aided samples: a change's continuity anchor and the
  wheel/INS consistency noise;
* :mod:`.records` -- the sample's inputs, a detected change and a finished reading, as the
  parts exchange them;
* :mod:`.aid_decision` -- :class:`~.aid_decision.AidDecision`, what the filter is told.
"""
