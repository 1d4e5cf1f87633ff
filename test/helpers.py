"""Helpers shared by the tests (``test/`` is on ``sys.path`` through ``test/conftest.py``).

* Where the team's real Pathfinder logs live (../shared/data/pathfinder beside the repo; never
  copied into it), and the skip every test that needs them takes when they are absent.
* :func:`score_sim_drive`: a simulated drive through the core, scored against the simulator's
  truth (the product's acceptance figures and the undeclared-effects tests).
* :func:`synthetic_messages` / :func:`synthetic_params` / :func:`write_synthetic_bag`: a small
  synthetic drive as ROS messages or a bag (replay, node, alignment and user-error tests).
* :func:`one_line_exit_2`: a command fails with one stderr line and exit status 2.
"""
from pathlib import Path

import numpy as np
import pytest

from slip_estimator.core.params import Params
from slip_estimator.effects import Effects, score_on_sim
from slip_estimator.sim import short_scenario, simulate
from slip_estimator.sim.bag import sim_params

DATA_DIR = Path(__file__).resolve().parents[1].parent / 'shared' / 'data' / 'pathfinder'


def mat_or_skip(name: str) -> Path:
    """Path of ``<name>.mat``; skips the calling test with a clear message when absent."""
    path = DATA_DIR / f'{name}.mat'
    if not path.exists():
        pytest.skip(f'Pathfinder log {path} not found (real data lives in '
                    '<repo>/../shared/data/pathfinder; not part of the repo)')
    return path


def score_sim_drive(seed: int, effects: Effects = Effects(), scenario=short_scenario, **overrides):
    """Feed a simulated drive (with optional undeclared effects) through the core in stamp
    order (:func:`slip_estimator.effects.score_on_sim`); return the slip result and the
    forward-speed RMSE while moving."""
    r = simulate(scenario(seed))
    score = score_on_sim(r, sim_params(r).replace(**overrides), effects)
    return score.slip, score.speed_rmse_mps


T0_NS = 1_700_000_000 * 1_000_000_000
G_MPS2 = 9.80
WHEEL_RADIUS_M = 0.12
JOINTS = ('front_left_wheel_joint', 'front_right_wheel_joint',
          'rear_left_wheel_joint', 'rear_right_wheel_joint')


def synthetic_messages(stationary_s: float = 10.0, drive_s: float = 10.0, *,
                       imu_hz: int = 250, wheel_hz: int = 50, speed_mps: float = 0.4,
                       accel_mps2: float = 0.2, slip: float = 0.3,
                       seed: int = 0) -> list[tuple[str, object, int]]:
    """(topic, message, log_time_ns) of a level, straight drive along base_link x.

    Stationary for ``stationary_s``, then accelerating at ``accel_mps2`` to ``speed_mps``;
    wheels turn at rim = v / (1 - slip) (paper eq. 1). IMU z up (REP-145: +g at rest), small
    seeded white noise. Log times lag the stamps (1 ms IMU, 7 ms wheels), so log order and
    stamp order differ, as in a real recording.
    """
    from sensor_msgs.msg import Imu, JointState

    from slip_estimator.ros.convert import ns_to_stamp

    rng = np.random.default_rng(seed)
    out: list[tuple[str, object, int]] = []
    total_s = stationary_s + drive_s

    def speed(t: float) -> tuple[float, float]:
        if t < stationary_s:
            return 0.0, 0.0
        v = min(speed_mps, accel_mps2 * (t - stationary_s))
        return v, (accel_mps2 if v < speed_mps else 0.0)

    for k in range(int(total_s * imu_hz)):
        t = k / imu_hz
        _, a = speed(t)
        msg = Imu()
        stamp_ns = T0_NS + k * (1_000_000_000 // imu_hz)
        msg.header.stamp = ns_to_stamp(stamp_ns)
        msg.header.frame_id = 'imu_link'
        f = np.array([a, 0.0, G_MPS2]) + rng.normal(0.0, 0.01, 3)
        w = rng.normal(0.0, 0.001, 3)
        msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = f
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w
        msg.orientation_covariance[0] = -1.0
        out.append(('/imu/data', msg, stamp_ns + 1_000_000))
    for k in range(int(total_s * wheel_hz)):
        t = k / wheel_hz
        v, _ = speed(t)
        rim = v / (1.0 - slip) if v > 0.0 else 0.0
        msg = JointState()
        stamp_ns = T0_NS + k * (1_000_000_000 // wheel_hz)
        msg.header.stamp = ns_to_stamp(stamp_ns)
        msg.name = list(JOINTS)
        msg.velocity = [rim / WHEEL_RADIUS_M] * 4
        msg.position = [0.0] * 4
        out.append(('/joint_states', msg, stamp_ns + 7_000_000))
    out.sort(key=lambda item: item[2])
    return out


def synthetic_params() -> Params:
    """Parameters matching the synthetic bag."""
    return Params(wheel_radius=WHEEL_RADIUS_M, wheel_input='joint_states',
                  wheel_joint_names=list(JOINTS))


def write_synthetic_bag(path: Path, messages=None, *, sqlite3: bool = False) -> Path:
    """Write ``messages`` (default: :func:`synthetic_messages`) as MCAP or sqlite3 bag."""
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from slip_estimator.bagio import BagWriter, message_type_name

    messages = synthetic_messages() if messages is None else messages
    if not sqlite3:
        with BagWriter(path) as writer:
            for topic, msg, log_ns in messages:
                writer.write(topic, msg, log_ns)
        return path
    typestore = get_typestore(Stores.ROS2_JAZZY)
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3)
    writer.open()
    conns = {}
    for topic, msg, log_ns in messages:
        if topic not in conns:
            conns[topic] = writer.add_connection(topic, message_type_name(msg),
                                                 typestore=typestore)
        writer.write(conns[topic], log_ns, serialize_message(msg))
    writer.close()
    return path


def one_line_exit_2(main, capsys, argv, *words):
    """``main(argv)`` exits 2 with one stderr line holding ``words`` and no traceback."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'Traceback' not in err, err
    for w in words:
        assert w in err, err
