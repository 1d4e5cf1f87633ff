"""Self-diagnosis: watch the filter's residuals and name the unmodelled effect they point to.

Each pseudo-measurement channel keeps exponentially weighted statistics of its normalised
innovations ``nu_i / sqrt(S_ii)``: the mean square (1 when the model fits, the per-channel NIS)
and the mean (0 when the model fits). A large mean square says the channel's noise model is
wrong; a persistent signed mean says something systematic is missing. The mapping from a
symptom to a suspect is physics, stated with each rule below; it is a hint for the operator,
not a proof.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from slip_estimator.core.slip_model.model import SlipModel

CHANNELS = ('zupt', 'zaru', 'nhc_lateral', 'nhc_vertical', 'wheel', 'wheel_yaw')


class ResidualMonitor:
    """Exponentially weighted residual statistics per channel, and the suspects they imply.

    Parameters
    ----------
    weight : EMA weight of a new update (0.02: about the last 50 updates, 5 s at 10 Hz).
    """

    def __init__(self, weight: float = 0.02) -> None:
        self.weight = weight
        self.mean = dict.fromkeys(CHANNELS, 0.0)
        self.mean_square = dict.fromkeys(CHANNELS, float('nan'))
        self.count = dict.fromkeys(CHANNELS, 0)
        self.held_slip_mean = float('nan')
        self.held_slip_count = 0
        self.unexplained_yaw_rps = float('nan')
        self._unexplained_yaw_std_rps = float('inf')

    def add(self, channel: str, innovation: np.ndarray, S: np.ndarray) -> None:
        """Add the normalised innovation of one update (one component per call or a vector
        whose components are averaged)."""
        # Scalars in Python floats: this runs on every update (most have one or two rows).
        self._add(channel, np.asarray(innovation, dtype=float).tolist(), np.diag(S).tolist())

    def _add(self, channel: str, innovation: list[float], var: list[float]) -> None:
        """:meth:`add` of the innovation and the diagonal of S as floats."""
        z = [nu / math.sqrt(max(v, 1e-300)) for nu, v in zip(innovation, var)]
        w = self.weight if self.count[channel] else 1.0
        self.mean[channel] += w * (sum(z) / len(z) - self.mean[channel])
        ms = sum(x * x for x in z) / len(z)
        prev = self.mean_square[channel]
        self.mean_square[channel] = ms if math.isnan(prev) else prev + w * (ms - prev)
        self.count[channel] += 1

    def add_update(self, name: str, innovation: np.ndarray, S: np.ndarray,
                   channels: tuple[str, ...] | None = None) -> None:
        """One update of model ``name``: as one channel, or one channel per row."""
        if channels is None:
            self.add(name, innovation, S)
            return
        # The rows' floats taken once (not two array slices and conversions per row).
        nu, var = np.asarray(innovation, dtype=float).tolist(), np.diag(S).tolist()
        for i, channel in enumerate(channels):
            self._add(channel, nu[i:i + 1], var[i:i + 1])

    def add_held_slip(self, s_hold: float) -> None:
        """A slip value the hold-mode aid settled on during ordinary (low-slip) driving."""
        if abs(s_hold) > 0.2:
            return
        w = 0.1 if self.held_slip_count else 1.0
        prev = 0.0 if math.isnan(self.held_slip_mean) else self.held_slip_mean
        self.held_slip_mean = prev + w * (s_hold - prev)
        self.held_slip_count += 1

    def add_yaw_disagreement(self, rate_rps: float, declared_std_rps: float) -> None:
        """The running mean of the wheel yaw-rate aid's innovation (the body's yaw rate its
        wheel differential does not show, rad/s, left positive: the FRD innovation wheels minus
        gyro) and the 1-sigma the parameters declare for it."""
        self.unexplained_yaw_rps = rate_rps
        self._unexplained_yaw_std_rps = declared_std_rps

    def suspects(self, min_updates: int = 30) -> list[str]:
        """Named likely unmodelled effects, most specific first."""
        out = []
        ms, mean, n = self.mean_square, self.mean, self.count
        if n['nhc_lateral'] >= min_updates and abs(mean['nhc_lateral']) > 1.0:
            # A heading misalignment of the IMU makes the forward speed leak into the lateral
            # axis with one sign; skid or side slopes do not keep one sign while driving.
            out.append('lateral velocity residual biased (%+.1f sigma): IMU yaw mounting off '
                       'its declared rotation, or a steady side slope/crab' % mean['nhc_lateral'])
        if n['nhc_vertical'] >= min_updates and abs(mean['nhc_vertical']) > 1.0:
            out.append('vertical velocity residual biased (%+.1f sigma): IMU pitch mounting off '
                       'its declared rotation, or a lever arm missing' % mean['nhc_vertical'])
        if n['zaru'] >= min_updates and ms['zaru'] > 4.0:
            out.append('zero-rate residuals %.0fx expected at rest: gyro noise/bias model too '
                       'optimistic or the rover vibrates while stopped' % ms['zaru'])
        if n['zupt'] >= min_updates and ms['zupt'] > 4.0:
            out.append('zero-velocity residuals %.0fx expected: accelerometer bias drifting or '
                       'the stationarity detector fires while moving' % ms['zupt'])
        if n['wheel'] >= min_updates and ms['wheel'] > 4.0:
            out.append('wheel-aid residuals %.0fx expected: slip changing faster than the hold '
                       'model, or wheel timestamps offset from the IMU' % ms['wheel'])
        if abs(self.unexplained_yaw_rps) > 3.0 * self._unexplained_yaw_std_rps:
            # Wheels that say straight while the body yaws: one side slips more (softer
            # ground, a side slope) or the gyro z bias is off (not yet learnt, or changing).
            out.append('body yaws %+.2f deg/s (left positive) more than its wheel differential '
                       'says: one side slipping more (soft ground, side slope), or the gyro z '
                       'bias not yet known' % math.degrees(self.unexplained_yaw_rps))
        if self.held_slip_count >= 2 and abs(self.held_slip_mean) > 0.1:
            # On ordinary ground a constant slip in every driving segment is what a wrong
            # wheel radius looks like: s = 1 - r_eff / r. Loose soil slips a few per cent
            # everywhere too, so only a large constant slip is reported.
            out.append('slip of %+.2f in all ordinary driving: wheel radius may be off by '
                       'about %.0f %% (or the terrain always slips; radius and slip cannot be '
                       'told apart without a speed reference)'
                       % (self.held_slip_mean, 100.0 * self.held_slip_mean))
        return out

    def values(self) -> dict[str, float]:
        """Figures for /diagnostics."""
        out = {}
        for c in CHANNELS:
            out[f'nis_per_dof_{c}'] = self.mean_square[c]
            out[f'residual_mean_sigma_{c}'] = self.mean[c] if self.count[c] else float('nan')
        out['held_slip_mean'] = self.held_slip_mean
        out['unexplained_yaw_rate_rps'] = self.unexplained_yaw_rps
        return out


_RESOLUTION_LIMIT = 0.2
"""Body-side slip changes are resolved only beyond this (the low class's width): above it a
medium slip that shows only in the IMU is missed (named in the health report)."""


def slip_model_figures(model: SlipModel) -> tuple[dict, str | None]:
    """The slip model's figures for /diagnostics and, when the IMU cannot resolve body-side
    slip changes of the low class's width at the current rim speed, a note naming the limit.

    ``slip_body_side_resolution``: the smallest body-side slip change the step test takes
    for one at the last rim speed (its threshold over the rim speed; NaN at rest): the
    IMU's own INS scatter, learned while driving, over the speed it has to be told from.
    """
    w = model.rim_speed_mps
    resolution = model.body_change_mps(w) / abs(w) if w else math.nan
    spread_mps = math.sqrt(model.spread_var[0])
    values = {'slip_model_mode': model.mode.value,
              'slip_hold': model.slip_hold if model.slip_hold is not None else math.nan,
              'slip_baseline': model.baseline if model.baseline is not None else math.nan,
              'slip_changes_wheel_side': model.changes['wheel'],
              'slip_changes_body_side': model.changes['body'],
              'slip_residual_spread_1s_mps': spread_mps,
              'slip_body_side_resolution': resolution}
    note = None
    if resolution > _RESOLUTION_LIMIT:  # False for NaN
        note = ('limit: body-side slip changes under %.2f are not resolved at %.2f m/s (INS '
                'scatter %.3f m/s over 1 s): a slowing body at steady wheels is read only '
                'beyond that, wheel-side changes as before' % (resolution, abs(w), spread_mps))
    return values, note
