"""Collision distances against closed forms (point-segment, point-box, segment-segment)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ffsr_gym.exceptions import RobotFileError
from ffsr_gym.model.collision import BoxObstacle, CollisionModel, SphereObstacle

CAPSULE_RADIUS = 0.02  # envs/robots/ffsr_dual_arm/collision.toml
BASE_HALF = 0.4


def _segments(robot, q):
    """Capsule axes from the joint origins, computed with plain forward kinematics."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    segments = {}
    for arm, name in enumerate(("mission", "balance")):
        pts = [data.oMi[int(j)].translation.copy() for j in robot.joint_ids[arm]]
        pts.append(data.oMf[int(robot.ee_frame_ids[arm])].translation.copy())
        for link, (a, b) in zip((1, 2, 4, 6), ((0, 1), (1, 2), (3, 4), (5, 6))):
            segments[f"{name}_link{link}"] = (pts[a], pts[b])
    return segments, data.oMi[1]


def _point_segment(p, a, b):
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(p - (a + t * (b - a)))


def _point_box_signed(p, base):
    local = base.rotation.T @ (p - base.translation)
    d = np.abs(local) - BASE_HALF
    outside = np.linalg.norm(np.maximum(d, 0.0))
    return outside if outside > 0 else float(np.max(d))


def _segment_segment(a0, a1, b0, b1):
    """Closest distance of two segments (clamped closed form, Ericson's algorithm)."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, f = d1 @ d1, d2 @ d2, d2 @ r
    c, b = d1 @ r, d1 @ d2
    denom = a * e - b * b
    s = np.clip((b * f - c * e) / denom, 0, 1) if denom > 1e-14 else 0.0
    t = (b * s + f) / e
    if t < 0:
        t, s = 0.0, np.clip(-c / a, 0, 1)
    elif t > 1:
        t, s = 1.0, np.clip((b - c) / a, 0, 1)
    return np.linalg.norm(a0 + s * d1 - (b0 + t * d2))


def _expected_sphere_distance(robot, q, center, radius):
    segments, base = _segments(robot, q)
    per_part = {name: _point_segment(center, a, b) - CAPSULE_RADIUS for name, (a, b) in segments.items()}
    per_part["base"] = _point_box_signed(center, base)
    name = min(per_part, key=per_part.get)
    return per_part[name] - radius, name


def test_sphere_distance_matches_closed_form_including_penetration(robot, collision_model, q_paper):
    rng = np.random.default_rng(0)
    segments, base = _segments(robot, q_paper)
    centers = []
    for a, b in segments.values():  # points near every capsule: outside, touching, inside
        for offset in (0.3, 0.05, 0.02, 0.01, 0.0):
            direction = np.cross(b - a, rng.normal(size=3))
            centers.append(a + rng.uniform(0.2, 0.8) * (b - a) + offset * direction / np.linalg.norm(direction))
    centers += [base.translation + rng.uniform(-0.6, 0.6, 3) for _ in range(20)]  # around and inside the base
    penetrating = 0
    for center in centers:
        for radius in (0.0, 0.05):
            expected, part = _expected_sphere_distance(robot, q_paper, center, radius)
            got = collision_model.obstacle_proximity(q_paper, [SphereObstacle(center, radius)])
            assert got.distance_m == pytest.approx(expected, abs=1e-9)
            assert got.pair == (part, "obstacle") or abs(got.distance_m - expected) < 1e-9
            penetrating += expected < 0
    assert penetrating > 10


def test_witness_points_lie_at_the_reported_distance(collision_model, q_paper):
    center = np.array([0.9, 0.45, 0.1])
    got = collision_model.obstacle_proximity(q_paper, [SphereObstacle(center, 0.0)])
    assert np.linalg.norm(got.witness_points[0] - got.witness_points[1]) == pytest.approx(abs(got.distance_m), abs=1e-9)
    assert np.allclose(got.witness_points[1], center)


def test_arm_arm_distance_matches_segment_closed_form(robot, collision_model):
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = robot.configuration(base_position_m=np.zeros(3), base_quaternion_wxyz=np.array([1.0, 0, 0, 0]),
                                joints_rad=rng.uniform(-np.pi, np.pi, 12))
        segments, _ = _segments(robot, q)
        expected = min(
            _segment_segment(*segments[m], *segments[b]) - 2 * CAPSULE_RADIUS
            for m in segments if m.startswith("mission") for b in segments if b.startswith("balance")
        )
        got = collision_model.arm_arm_proximity(q)
        assert got.distance_m == pytest.approx(expected, abs=1e-9)
        assert got.pair[0].startswith("mission") and got.pair[1].startswith("balance")


def test_arm_base_distance_excludes_the_mounting_links(collision_model, q_paper):
    got = collision_model.arm_base_proximity(q_paper)
    # mission link 2 starts 0.1 m above the base's top face (z = 0.3248 + 0.4), then goes down/out.
    assert got.pair == ("mission_link2", "base")
    assert got.distance_m > 0


def test_box_obstacle_distance_matches_closed_form(robot, collision_model, q_paper):
    """A box obstacle is checked against the closed form of its nearest corner region."""
    segments, base = _segments(robot, q_paper)
    rng = np.random.default_rng(5)
    for _ in range(10):
        center = base.translation + rng.uniform(-1.5, 1.5, 3)
        half = 1e-4  # a small cube: its distance is the point distance minus at most sqrt(3) * half
        expected, _ = _expected_sphere_distance(robot, q_paper, center, 0.0)
        got = collision_model.obstacle_proximity(q_paper, [BoxObstacle(center, np.full(3, 2 * half))])
        assert expected - np.sqrt(3) * half - 1e-9 <= got.distance_m <= expected - half + 1e-9


def test_missing_collision_file(robot, tmp_path):
    with pytest.raises(RobotFileError, match="does not exist"):
        CollisionModel(robot, tmp_path / "none.toml")


def test_malformed_collision_file(robot, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('capsule_radius_m = 0.02\n[base]\nlink = "base"\nsize_m = [0.8, 0.8, 0.8]\n'
                    '[[capsule]]\nlink = "no_such_link"\nstart_m = [0, 0, 0]\nend_m = [0, 0, 1]\n')
    with pytest.raises(RobotFileError, match="no_such_link"):
        CollisionModel(robot, path)
