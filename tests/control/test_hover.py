"""The hover-tracking controller."""

from __future__ import annotations

import numpy as np

from ihrcf_env.control.hover import HoverGains, HoverTracker, tracking_action
from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix


def test_tracking_action_follows_the_estimate_and_holds_when_invalid() -> None:
    level = np.array([0.0, 0.0, 0.0, 1.0])
    mv = np.ones(4)
    est = {"position": np.array([0.1, -0.2, -1.1]), "euler": np.array([0.0, 0.0, 0.3]), "valid": 1}
    a = tracking_action(est, level, 1.0, mv)
    assert a[0] > 0 and a[1] < 0 and a[2] < 0 and a[3] > 0  # towards the deck, down to 1 m, turn with it
    assert np.all(np.abs(a) <= 1.0)
    assert np.all(tracking_action({**est, "valid": 0}, level, 1.0, mv) == 0.0)
    # a tilted drone straight over the deck, 1 m up: the tilt must not read as an offset
    R = matrix_from_euler(0.1, -0.15, 0.7)
    est_tilted = {"position": R.T @ np.array([0.0, 0.0, -1.0]), "euler": np.zeros(3), "valid": 1}
    a = tracking_action(est_tilted, quat_from_matrix(R), 1.0, mv)
    assert np.allclose(a, 0.0, atol=1e-9)


def test_gains_scale_and_max_velocity_normalise() -> None:
    level = np.array([0.0, 0.0, 0.0, 1.0])
    est = {"position": np.array([0.1, -0.2, -1.1]), "euler": np.array([0.0, 0.0, 0.3]), "valid": 1}
    a = tracking_action(est, level, 1.0, (2.0, 2.0, 2.0, 2.0), HoverGains(k_xy=2.0, k_z=0.5, k_yaw=3.0))
    assert np.allclose(a, [0.1, -0.2, 0.5 * -0.1 / 2.0, 3.0 * 0.3 / 2.0])


def test_tracker_policy_reads_the_chosen_estimator() -> None:
    level = np.array([0.0, 0.0, 0.0, 1.0])
    est = {"position": np.array([0.1, -0.2, -1.1]), "euler": np.array([0.0, 0.0, 0.3]), "valid": 1}
    none = {"position": np.zeros(3), "euler": np.zeros(3), "valid": 0}
    obs = {"ihrcf": none, "atda": est, "imu": {"quaternion": level}}
    assert np.all(HoverTracker().act(obs) == 0.0)
    assert np.allclose(HoverTracker(estimator="atda").act(obs), tracking_action(est, level, 1.0, np.ones(4)))
