"""Render a ``setup`` result: the commented params file and the one-screen report."""
from __future__ import annotations

import dataclasses
import math

from slip_estimator.core.params import Params, describe
from slip_estimator.paramfile import NODE_NAME, _yaml_value
from slip_estimator.robot_setup.decide import Proposal
from slip_estimator.robot_setup.measure import Measured
from slip_estimator.robot_setup.scan import Scan
from slip_estimator.robot_setup.signals import Figure


def params_text(p: Proposal, bag: str) -> str:
    """The params file: every parameter with its value and, on the line above, its meaning and
    where the value came from (measured / declared / default / bag)."""
    lines = [f'# slip_estimator parameters written by `slip-estimator setup {bag}`.',
             '# Each value says where it came from: measured (on that bag, with its spread and',
             '# samples), declared (the --declared file), default (the schema), bag (topic',
             '# names found by type). Replay with: slip-estimator replay BAG --params-file THIS',
             f'{NODE_NAME}:', '  ros__parameters:']
    for f in dataclasses.fields(Params):
        lines.append(f'    # {describe(f.name)}')
        lines.append(f'    #   <- {p.sources[f.name]}')
        lines.append(f'    {f.name}: {_yaml_value(getattr(p.params, f.name))}')
    return '\n'.join(lines) + '\n'


def _fig(fig: Figure, fmt: str, unit: str) -> str:
    if not fig.ok:
        return f'not measured ({fig.why})'
    spread = f' +- {fig.spread:{fmt}}' if math.isfinite(fig.spread) else ''
    return f'{fig.value:{fmt}}{spread} {unit} ({fig.n} samples)'


def report_text(bag: str, scan: Scan, m: Measured, p: Proposal, out: str,
                declared: Params) -> str:
    """The one-screen report: topics, IMU checks, the figures, problems, what to check."""
    imu, mount, noise = m.imu, m.mounting, m.noise
    lines = [f'slip-estimator setup {bag}: {m.duration_s:.1f} s of data']
    lines += ['  ' + s.line() for s in scan.stats]
    remaps = [f'-r {src}:={dst}' for src, dst in
              ((scan.imu_topic, '/imu/data'),
               (scan.wheel_topic, '/joint_states' if scan.wheel_input == 'joint_states'
                else '/wheel/odometry')) if src != dst]
    lines.append(f'inputs: IMU {scan.imu_topic}, wheels {scan.wheel_topic} ({scan.wheel_input}'
                 + (f': {", ".join(scan.joint_names)}' if scan.joint_names else '') + '), GNSS '
                 + (scan.gnss_topic or 'none') + ('; remaps (in the file as *_topic): '
                                                  + ' '.join(remaps) if remaps else ''))
    f = imu.f_rest_imu_mps2
    rest = (f'|f| at rest {math.sqrt(sum(x * x for x in f)):.2f} m/s^2 over '
            f'{imu.rest_samples} samples' if f else 'no rest')
    lines.append(f'IMU: gravity {imu.gravity} ({rest}); gyro units '
                 f'{imu.gyro_units or "undecided"}; '
                 + ('; '.join(imu.clipping) if imu.clipping else 'no clipping'))
    if mount.rpy_rad is not None:
        deg = ', '.join(f'{math.degrees(a):.1f}' for a in mount.rpy_rad)
        lines.append(f'mounting: rpy ({deg}) deg {"exact (axis-aligned)" if mount.exact else ""}'
                     f' - up from {mount.up_from}, forward angle +- '
                     f'{mount.yaw_deg.spread:.2f} deg over {mount.yaw_deg.n} samples')
    else:
        lines.append('mounting: UNDECIDED (' + '; '.join(mount.notes) + ')')
    lines.append(f'noise at rest ({noise.rest_s:.0f} s): accel '
                 f'{_fig(noise.accel_density_mps2_rthz, ".2e", "m/s^2/rtHz")}, gyro '
                 f'{_fig(noise.gyro_density_rps_rthz, ".2e", "rad/s/rtHz")}'
                 + (', gyro bias (' + ', '.join(f'{x:.1e}' for x in noise.gyro_bias_imu_rps)
                    + ') rad/s' if noise.gyro_bias_imu_rps else ''))
    lines.append(f'wheel-to-IMU lag: {_fig(m.lag_s, ".3f", "s")}')
    track = m.track_m
    ratio = (f' = {track.value / declared.track_width:.2f} x the declared '
             f'{declared.track_width:.3f} m' if track.ok else '')
    lines.append(f'effective track: {_fig(track, ".3f", "m")}{ratio}')
    lines.append(f'wheel radius ratio (GNSS/rim, straight runs): '
                 f'{_fig(m.radius_ratio, ".3f", "")}'.rstrip())
    st = m.start
    if st.llh_deg_deg_m:
        lat, lon, h = st.llh_deg_deg_m
        head = (f', heading {st.heading.heading_deg:.1f} deg' if st.heading
                else f', heading not measured ({st.why})')
        lines.append(f'start: {lat:.6f}, {lon:.6f} deg, {h:.1f} m{head}')
    for line in p.problems:
        lines.append(f'PROBLEM: {line}')
    for line in p.checks:
        lines.append(f'check: {line}')
    lines.append(f'wrote {out}; next: slip-estimator replay {bag} --params-file {out} '
                 '-o estimate')
    return '\n'.join(lines)
