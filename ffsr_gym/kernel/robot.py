"""The native kernel's typed robot (C++17, ``ffsr_gym._native``, compiled at install), built from the arrays
:mod:`ffsr_gym.kernel.arrays` extracts from the URDF.

The native routines compile without floating-point contraction or fast-math, so the same source gives the same
bits on every x86-64 and aarch64 build (docs/kernel.md).
"""

from __future__ import annotations

import numpy as np

from ffsr_gym._native import Robot
from ffsr_gym.kernel.arrays import KernelModel

#: The fields of :class:`~ffsr_gym.kernel.arrays.KernelModel` the native robot takes, with their dtypes.
ROBOT_FIELDS = {"parent": np.int64, "placement_R": float, "placement_p": float, "axis": float, "axis_code": np.int64,
                "mass": float, "lever": float, "inertia": float, "ee_parent": np.int64, "ee_R": float, "ee_p": float,
                "cap_parent": np.int64, "cap_a": float, "cap_b": float, "cap_radius": float, "cap_arm": np.int64,
                "cap_vs_base": np.int64, "box_half": float}


def robot_arrays(model: KernelModel) -> dict[str, np.ndarray]:
    """The arrays :meth:`ffsr_gym._native.Robot.from_arrays` takes, by name, from a kernel model (contiguous, of
    :data:`ROBOT_FIELDS`' dtypes)."""
    return {name: np.ascontiguousarray(getattr(model, name), dtype=dtype) for name, dtype in ROBOT_FIELDS.items()}


def native_robot(model: KernelModel) -> Robot:
    """The native :class:`ffsr_gym._native.Robot` of a kernel model (a wrong shape: ``ValueError`` naming it)."""
    return Robot.from_arrays(**robot_arrays(model))


def native_plant(model: KernelModel, plant: tuple) -> Robot:
    """The robot the physics integrates: ``model``'s kinematics with the plant's (mass, lever, inertia, drive)
    (``ffsr_gym.sim.setup.ScenarioSetup.plant_arrays``; drive zeros for the kinematic plant)."""
    mass, lever, inertia, drive = plant
    fields = robot_arrays(model) | {"mass": np.ascontiguousarray(mass, float),
                                    "lever": np.ascontiguousarray(lever, float),
                                    "inertia": np.ascontiguousarray(inertia, float)}
    return Robot.from_arrays(**fields, drive=np.ascontiguousarray(drive, float))
