"""Signed distances between the robot's collision geometry and obstacles, and between its parts.

The geometry (a capsule per link, a box for the base) is read from ``collision.toml`` next to the
robot's URDF and queried with coal, the collision library that ships with Pinocchio (docs/install.md
records why coal rather than python-fcl: exact closed-form primitives and ~2x faster queries).
Distances are signed: negative on penetration. Every query returns the closest pair of geometry
names and the witness points.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from ffsr_gym.exceptions import RobotFileError
from ffsr_gym.model import portable
from ffsr_gym.model.robot import Robot
from ffsr_gym.types import Array
from ffsr_gym.user_files import check_depth, read_text

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@dataclass(frozen=True)
class SphereObstacle:
    """A sphere obstacle: centre [m] and radius [m] (radius 0 is a point)."""

    center_m: Array
    radius_m: float = 0.0
    name: str = "obstacle"


@dataclass(frozen=True)
class BoxObstacle:
    """A box obstacle: centre [m], edge lengths [m] and rotation (3x3, box to world)."""

    center_m: Array
    size_m: Array
    rotation: Array = field(default_factory=lambda: np.eye(3))
    name: str = "box"


Obstacle = SphereObstacle | BoxObstacle


@dataclass(frozen=True)
class Proximity:
    """Result of a distance query.

    Attributes:
        distance_m: signed distance [m], negative on penetration (+inf if nothing was checked).
        pair: names of the two closest geometries (robot part first).
        witness_points: (2, 3) closest points [m] on each, in the inertial frame.
    """

    distance_m: float
    pair: tuple[str, str]
    witness_points: Array


_NOTHING = Proximity(np.inf, ("", ""), np.full((2, 3), np.nan))


@dataclass
class _Part:
    name: str
    arm: str  # "mission", "balance" or "base"
    shape: coal.CollisionGeometry
    frame_id: int
    local: pin.SE3


def _segment_frame(start: Array, end: Array) -> pin.SE3:
    """Frame at the segment midpoint whose z axis points from ``start`` to ``end``."""
    axis = (end - start) / portable.norm(end - start)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, axis)
    x /= portable.norm(x)
    return pin.SE3(np.column_stack((x, np.cross(axis, x), axis)), 0.5 * (start + end))


class CollisionModel:
    """The collision geometry of a :class:`~ffsr_gym.model.robot.Robot`, placed at a configuration."""

    def __init__(self, robot: Robot, spec_path: str | Path | None = None) -> None:
        path = Path(spec_path) if spec_path else robot.urdf_path.parent / "collision.toml"
        if not path.is_file():
            raise RobotFileError(f"collision file {str(path)!r} does not exist")
        try:
            text = read_text(path)
            check_depth(text, str(path))
            spec = tomllib.loads(text)
            self._parts = self._read_parts(robot, spec)
            self._ignored = _ignored_pairs(spec["base"].get("ignored_pairs", []), [p.name for p in self._parts])
        except (KeyError, TypeError, ValueError, tomllib.TOMLDecodeError) as exc:
            raise RobotFileError(f"collision file {path} is malformed: {exc}") from None
        self.robot = robot
        self.spec_path = path
        self._request = coal.DistanceRequest()
        self._placements: list[coal.Transform3s] = []

    def __reduce__(self) -> tuple:
        """Pickle as (robot, collision file); the coal shapes are rebuilt on load."""
        return (CollisionModel, (self.robot, self.spec_path))

    @staticmethod
    def _read_parts(robot: Robot, spec: dict) -> list[_Part]:
        """The base box and the capsules, each checked: named after a link of its arm, sizes finite and positive."""
        model = robot.model
        radius = _length(spec.get("capsule_radius_m"), "capsule_radius_m")
        base = spec["base"]
        if not isinstance(base, dict) or not isinstance(base.get("link"), str):
            raise ValueError("[base]: allowed: a table with link (text) and size_m (three lengths [m])")
        if not model.existFrame(base["link"]) or model.frames[model.getFrameId(base["link"])].parentJoint != 1:
            raise ValueError(f"base.link {base['link']!r} is not the URDF's root link")
        size = _vector(base.get("size_m"), "base.size_m")
        if np.any(size <= 0.0):
            raise ValueError(f"base.size_m = {base['size_m']!r}; allowed: three finite edge lengths > 0 [m]")
        parts = [_Part("base", "base", coal.Box(*size), model.getFrameId(base["link"]), pin.SE3.Identity())]
        capsules = spec.get("capsule")
        if not isinstance(capsules, list) or not all(isinstance(item, dict) for item in capsules):
            raise ValueError(f"capsule = {capsules!r}; allowed: [[capsule]] tables, at least one per arm")
        for number, item in enumerate(capsules, start=1):
            link = item.get("link")
            if not isinstance(link, str):
                raise ValueError(f"capsule {number}: link = {link!r}; allowed: the name of a link (text)")
            where = f"capsule {number} (link {link!r})"
            arm = link.split("_")[0]
            if arm not in ("mission", "balance"):
                raise ValueError(f"{where}: a capsule's link is named <arm>_..., arm 'mission' or 'balance'")
            if not model.existFrame(link) or model.frames[model.getFrameId(link)].type != pin.FrameType.BODY:
                raise ValueError(f"{where}: no such link in the URDF")
            joint = int(model.frames[model.getFrameId(link)].parentJoint)
            if not model.names[joint].startswith(f"{arm}_joint"):
                raise ValueError(f"{where}: the link moves with {model.names[joint]!r}, not with a joint of the {arm} arm")
            start = _vector(item.get("start_m"), f"{where}: start_m")
            end = _vector(item.get("end_m"), f"{where}: end_m")
            r = _length(item.get("radius_m", radius), f"{where}: radius_m")
            length = portable.norm(end - start)
            if length <= 0.0:
                raise ValueError(f"{where}: start_m equals end_m; allowed: two different points (a segment)")
            shape = coal.Capsule(r, length)
            parts.append(_Part(link, arm, shape, model.getFrameId(link), _segment_frame(start, end)))
        for arm in ("mission", "balance"):
            if not any(part.arm == arm for part in parts):
                raise ValueError(f"no capsule on the {arm} arm; allowed: at least one [[capsule]] per arm")
        return parts

    @property
    def part_names(self) -> list[str]:
        """Names of the collision parts, base first."""
        return [p.name for p in self._parts]

    def place(self, q: Array) -> None:
        """Place every part at configuration ``q`` (runs forward kinematics)."""
        pin.framesForwardKinematics(self.robot.model, self.robot.data, q)
        self._placements = []
        for part in self._parts:
            world = self.robot.data.oMf[part.frame_id] * part.local
            self._placements.append(coal.Transform3s(world.rotation, world.translation))

    def _query(self, i: int, shape: coal.CollisionGeometry, placement: coal.Transform3s, other: str) -> Proximity:
        result = coal.DistanceResult()
        distance = coal.distance(self._parts[i].shape, self._placements[i], shape, placement, self._request, result)
        points = np.array([result.getNearestPoint1(), result.getNearestPoint2()])
        return Proximity(float(distance), (self._parts[i].name, other), points)

    def obstacle_proximity(self, q: Array, obstacles: Sequence[Obstacle], *, place: bool = True) -> Proximity:
        """Closest robot part (base included) to any obstacle, signed [m]."""
        if place:
            self.place(q)
        best = _NOTHING
        for obstacle in obstacles:
            shape, placement = _obstacle_geometry(obstacle)
            for i in range(len(self._parts)):
                best = _closer(best, self._query(i, shape, placement, obstacle.name))
        return best

    def _pairs_proximity(self, pairs: Iterable[tuple[int, int]]) -> Proximity:
        best = _NOTHING
        for i, j in pairs:
            if frozenset((self._parts[i].name, self._parts[j].name)) in self._ignored:
                continue
            best = _closer(best, self._query(i, self._parts[j].shape, self._placements[j], self._parts[j].name))
        return best

    def arm_arm_proximity(self, q: Array, *, place: bool = True) -> Proximity:
        """Closest pair between a mission-arm link and a balance-arm link, signed [m]."""
        if place:
            self.place(q)
        idx = {arm: [i for i, p in enumerate(self._parts) if p.arm == arm] for arm in ("mission", "balance")}
        return self._pairs_proximity((i, j) for i in idx["mission"] for j in idx["balance"])

    def arm_base_proximity(self, q: Array, *, place: bool = True) -> Proximity:
        """Closest pair between any arm link and the base (mounting links excluded), signed [m]."""
        if place:
            self.place(q)
        return self._pairs_proximity((i, 0) for i, p in enumerate(self._parts) if p.arm != "base")

    def self_proximity(self, q: Array, *, place: bool = True) -> Proximity:
        """The smaller of the arm-arm and arm-base proximities, signed [m]."""
        if place:
            self.place(q)
        return _closer(self.arm_arm_proximity(q, place=False), self.arm_base_proximity(q, place=False))

    def clearance(self, q: Array, obstacles: Sequence[Obstacle]) -> Proximity:
        """The smallest of obstacle, arm-arm and arm-base proximities, signed [m]."""
        self.place(q)
        return _closer(self.obstacle_proximity(q, obstacles, place=False), self.self_proximity(q, place=False))


def _length(value: Any, where: str) -> float:
    """A finite length > 0 [m] from a TOML number (not a boolean, not a text)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{where} = {value!r}; allowed: a number > 0 [m]")
    return float(value)


def _vector(value: Any, where: str) -> Array:
    """[x, y, z] [m]: three finite TOML numbers."""
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)):
        raise ValueError(f"{where} = {value!r}; allowed: [x, y, z], three finite numbers [m]")
    return np.array(value, dtype=float)


def _ignored_pairs(value: Any, names: list[str]) -> set[frozenset[str]]:
    """``base.ignored_pairs``: a list of two-name lists, each naming two collision parts."""
    if not isinstance(value, list) or not all(isinstance(pair, list) and len(pair) == 2 and all(
            isinstance(name, str) and name in names for name in pair) for pair in value):
        raise ValueError(f"base.ignored_pairs = {value!r}; allowed: a list of [part, part] pairs, parts among {names}")
    return {frozenset(pair) for pair in value}


def _closer(a: Proximity, b: Proximity) -> Proximity:
    return b if b.distance_m < a.distance_m else a


def _obstacle_geometry(obstacle: Obstacle) -> tuple[coal.CollisionGeometry, coal.Transform3s]:
    center = np.asarray(obstacle.center_m, dtype=float)
    if isinstance(obstacle, SphereObstacle):
        return coal.Sphere(float(obstacle.radius_m)), coal.Transform3s(np.eye(3), center)
    return coal.Box(*map(float, obstacle.size_m)), coal.Transform3s(np.asarray(obstacle.rotation, float), center)
