"""Where a scenario's obstacles are at time t: ``[obstacle]`` and the ``[debris]`` list, drifting on straight lines.

Every obstacle is a sphere (radius 0 is a point) at p + v t. The planner's danger field, the
collision check and the observation all read positions from here (docs/model.md §14).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ffsr_gym.model.collision import SphereObstacle
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.types import Array


@dataclass(frozen=True)
class ObstacleField:
    """A scenario's obstacles: start positions (n, 3) [m], drift velocities (n, 3) [m/s], radii (n,) [m].

    Row 0 is ``[obstacle]``, then the ``[debris]`` rows in file order; n = 0 in free space.
    """

    positions_m: Array
    velocities_m_s: Array
    radii_m: Array

    def __len__(self) -> int:
        return len(self.radii_m)

    def at(self, t: float) -> Array:
        """Positions (n, 3) [m] at time ``t`` [s]: p + v t (exactly p for a still obstacle)."""
        return self.positions_m + self.velocities_m_s * t

    def spheres(self, t: float) -> tuple[SphereObstacle, ...]:
        """The obstacles as collision spheres at time ``t`` [s]."""
        return tuple(SphereObstacle(p, float(r), name="obstacle" if i == 0 else f"debris {i}")
                     for i, (p, r) in enumerate(zip(self.at(t), self.radii_m)))


def obstacle_field(scenario: Scenario) -> ObstacleField:
    """The :class:`ObstacleField` of a scenario."""
    obstacle, debris = scenario.obstacle, scenario.debris
    if obstacle is None:
        return ObstacleField(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    positions, velocities, radii = [obstacle.position_m], [(0.0, 0.0, 0.0)], [obstacle.radius_m]
    if debris is not None:
        velocities[0] = debris.obstacle_velocity_m_s
        positions += list(debris.positions_m)
        velocities += list(debris.velocities_m_s)
        radii += list(debris.radii_m)
    return ObstacleField(np.array(positions, dtype=float), np.array(velocities, dtype=float),
                         np.array(radii, dtype=float))
