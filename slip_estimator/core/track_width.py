"""Effective track width of a skid-steer robot, from the gyro and the wheel differential.

A skid-steer robot turns by scrubbing its wheels sideways: the rim-speed differential needed
for a yaw rate is larger than the geometric track predicts, rim_R - rim_L = B_eff * omega
(FLU yaw rate), with B_eff 1.5-1.9 times the wheel spacing on real robots (the multiplier
users hand-tune in diff-drive controllers). B_eff is the least-squares ratio over turning
samples, with a fading memory so that it follows the ground; a fit whose correlation is
below ``MIN_CORRELATION`` (the differential does not follow the yaw rate: wheels lifted,
tracks slipping, wrong joint sides) is no width, and the declared one stays. Only the
standard library is used.
"""
from __future__ import annotations

MIN_RATE_RPS = 0.1
"""Below this yaw rate the differential is encoder noise, not a turn."""
_MEMORY = 300
"""Turning samples the estimate remembers (30 s of turning at 10 Hz)."""
MIN_SAMPLES = 20
MIN_CORRELATION = 0.8
_RATIO_BOUNDS = (0.5, 3.0)
"""An estimate outside these multiples of the declared track is a fault, not a robot."""
_UNFITTED_RELATIVE_STD = 0.5
"""Before a fit the declared (geometric) track stands: a skid-steer robot's effective one is
1.5-1.9 times it, so the yaw rate the declared track gives may be off by half of itself."""


class TrackWidthEstimator:
    """rim_R - rim_L = B_eff * omega_FLU, fitted online."""

    def __init__(self, declared_m: float) -> None:
        self.declared_m = declared_m
        self._sxy = self._sxx = self._syy = 0.0
        self.samples = 0

    def add(self, yaw_rate_flu_rps: float, rim_right_minus_left_mps: float | None) -> None:
        """One yaw rate and the wheels' right minus left rim speed (None: not known, ignored)."""
        w = yaw_rate_flu_rps
        if rim_right_minus_left_mps is None or abs(w) < MIN_RATE_RPS:
            return
        self.samples += 1
        k = 1.0 / min(self.samples, _MEMORY)
        self._sxy += k * (w * rim_right_minus_left_mps - self._sxy)
        self._sxx += k * (w * w - self._sxx)
        self._syy += k * (rim_right_minus_left_mps ** 2 - self._syy)

    @property
    def correlation(self) -> float:
        """Correlation of the wheel differential with the yaw rate over the turns (about
        zero-mean pairs: left and right turns), 0 before any turn."""
        if self._sxx <= 0.0 or self._syy <= 0.0:
            return 0.0
        return self._sxy / (self._sxx * self._syy) ** 0.5

    @property
    def fitted(self) -> bool:
        """True once enough turning, correlated with the differential, was seen."""
        return self.samples >= MIN_SAMPLES and self.correlation >= MIN_CORRELATION

    @property
    def relative_var(self) -> float:
        """Relative variance of the yaw rate ``(rim_R - rim_L) / width_m`` in a turn: the
        share of the differential the fit leaves unexplained (1 - correlation^2: encoder and
        gyro noise, slip changing the scrub) once fitted, else ``_UNFITTED_RELATIVE_STD^2``."""
        if not self.fitted:
            return _UNFITTED_RELATIVE_STD ** 2
        return max(1.0 - self.correlation ** 2, 0.0)

    @property
    def width_m(self) -> float:
        """The effective track width, m (the declared one until enough turning is seen)."""
        if not self.fitted:
            return self.declared_m
        lo, hi = _RATIO_BOUNDS
        return min(max(self._sxy / self._sxx, lo * self.declared_m), hi * self.declared_m)
