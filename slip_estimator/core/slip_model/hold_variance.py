"""How well the held slip places the body's speed: the variance the wheel aid carries with a
hold and the variance the odometry guard judges it by, both read from the chain of changes
that led to the hold (:class:`~.chain.SlipChain`).

Only the standard library is used.
"""
from __future__ import annotations

import math

from slip_estimator.core.slip_model.chain import ASSUMED_SLIP_STD, RESOLVED_SIGMAS, SlipChain


def resolved(held: float | None, ins_var: float, w: float) -> bool:
    """The hold ``held`` puts the body beyond ``RESOLVED_SIGMAS`` of the INS's spread
    ``ins_var`` (m^2/s^2) from the rim speed ``w``: resolved from the rim whatever the chain."""
    return abs((held or 0.0) * w) > RESOLVED_SIGMAS * math.sqrt(ins_var)


def held_speed_var_mps2(chain: SlipChain, w: float, spread_var: float) -> float:
    """Body-speed variance of the held slip at rim speed ``w``, m^2/s^2: the INS spread of a
    measurement ``spread_var`` plus the chain since the last anchor; ``ASSUMED_SLIP_STD`` of
    ``w`` if nothing measured it (a start in motion), or the chain of changes measured from
    there if wider (on the 30-Hz consumer robot four such changes ratcheted the hold from 0 to
    0.46, truth 0.11, while the published sigma stayed at 0.10)."""
    if chain.assumed:
        return max((ASSUMED_SLIP_STD * w) ** 2, chain.chain_var)
    return spread_var + chain.chain_var


def assumed_hold(chain: SlipChain, held: float | None, ins_var: float, w: float) -> bool:
    """True where the odometry guard judges the hold ``held`` on an assumption: a chain that
    began in motion (``chain.assumed``: no stop measured the ground) moved by changes the INS
    alone read (``chain.ins_chain_var``) to a hold off the assumed slip, and the hold does not
    put the body beyond ``RESOLVED_SIGMAS`` of the INS's spread ``ins_var`` from the rim speed
    ``w``. On the 30-Hz consumer robot (``skid_steer_30hz`` seed 3) such holds, 0.33 kept 25 s
    after its sand patch ended and -0.14 read at a patch's end, on ground of 0.07, put the
    fused track 4.0 m behind and 4.7 m ahead of the body where the rim speed erred by 1.0 and
    1.3 m (:mod:`~slip_estimator.core.odometry_guard`). Only where the INS's spread itself
    exceeds the assumption's sigma (``ASSUMED_SLIP_STD`` of ``w``): an INS that places a
    change better than that keeps its hold (the Pathfinder's simulated IMU joined in motion
    on an uphill patch otherwise published the rim speed: 0.112 m/s RMS off over 20 s
    against 0.089 fused, ``test_alignment``)."""
    return chain.assumed and chain.ins_chain_var > 0.0 and held is not None and \
        held != (chain.baseline or 0.0) and not resolved(held, ins_var, w) and \
        ins_var > (ASSUMED_SLIP_STD * w) ** 2


def guard_var_mps2(chain: SlipChain, ins_var: float, held: float | None, w: float) -> float:
    """Body-speed variance the odometry guard judges, m^2/s^2: the INS's spread over a
    measuring span ``ins_var`` with the chain's since the last anchor added, as for the hold
    itself (:func:`held_speed_var_mps2`), but only the changes the INS alone read
    (``chain.ins_chain_var``: where the rim stepped and the body did not follow, the wheels are
    what changed; real test17run with its wheels spun x2.5 otherwise fell back onto the
    spinning rim, 1.14 m/s off). On an assumed chain (a start in motion) the larger of the
    two, and where the hold departs from the assumed slip (:func:`assumed_hold`) the
    assumption's variance (``ASSUMED_SLIP_STD`` of ``w``) is added to the chain: a change the
    INS read from the rim-aided speed places the body relative to a slip nothing measured, so
    its error is the assumption's and the change's together. The INS's spread alone where the
    hold ``held`` puts the body more than ``RESOLVED_SIGMAS`` of it from the rim speed ``w``
    (:func:`resolved`): resolved from the rim whatever the chain (test17run's injected
    body-side holds, 0.2-0.6 m/s from the rim at a chain of 0.11-0.15 m/s, were otherwise
    published at the rim: forward-speed RMSE 0.203 -> 0.260 m/s; a tactical IMU joined in
    motion held 0.41 on an uphill patch at 0.55 m/s, truth 0.55)."""
    chain_var = chain.ins_chain_var
    if resolved(held, ins_var, w):
        return ins_var
    if not chain.assumed:
        return ins_var + chain_var
    if assumed_hold(chain, held, ins_var, w):
        chain_var += (ASSUMED_SLIP_STD * w) ** 2
    return max(ins_var, chain_var)
