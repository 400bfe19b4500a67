"""Joint drives of the servo plant: a robot folder's ``drives/servo.toml``, loaded and validated.

The file lists, per arm and joint, the servo gain, torque limit, gear ratio, rotor inertia and
viscous friction, with the reference figures they were scaled from (its comments give every
source). :func:`drive_array` turns them into the kernel's (12, 4) array
(``ffsr_gym.kernel.servo``): gain, limit, armature = gear ratio² · rotor inertia, friction. The
file sits in a sub-folder so that the robot's hash, which every kinematic scenario carries,
does not change with it; a servo scenario hashes it as well (``Scenario.sha256``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ffsr_gym.exceptions import RobotFileError, ScenarioError
from ffsr_gym.model.schema import TEXT, Vec, integer, load_table, number, section, vector
from ffsr_gym.types import Array

#: Where a robot folder keeps its drives.
DRIVES_FILE = Path("drives") / "servo.toml"


@dataclass(frozen=True)
class ArmDrives:
    """One arm's six drives, joint 1 first, all at the joint (after the gearbox)."""

    servo_gain_Nm_s_per_rad: Vec = field(metadata=vector(6, 0.0, 1e6))
    torque_limit_Nm: Vec = field(metadata=vector(6, 0.0, 1e6))
    gear_ratio: Vec = field(metadata=vector(6, 1.0, 1e4))
    rotor_inertia_kg_m2: Vec = field(metadata=vector(6, 0.0, 1.0))
    viscous_friction_Nm_s_per_rad: Vec = field(metadata=vector(6, 0.0, 1e6))


@dataclass(frozen=True)
class DriveReference:
    """The figures the drives were scaled from: gain and limit of joints 1-3 and 4-6, that arm's link mass."""

    sources: str = field(metadata=TEXT)
    servo_gain_Nm_s_per_rad: Vec = field(metadata=vector(2, 0.0, 1e6))
    torque_limit_Nm: Vec = field(metadata=vector(2, 0.0, 1e6))
    arm_mass_kg: float = field(metadata=number(0.0, 1e6, lo_open=True))


@dataclass(frozen=True)
class Drives:
    """A robot's drive file."""

    schema_version: int = field(metadata=integer(1))
    reference: DriveReference = field(metadata=section(DriveReference))
    mission: ArmDrives = field(metadata=section(ArmDrives))
    balance: ArmDrives = field(metadata=section(ArmDrives))


def drives_path(robot_folder: Path) -> Path:
    """The drive file of a robot folder."""
    return Path(robot_folder) / DRIVES_FILE


@lru_cache(maxsize=8)
def load_drives(path: Path) -> Drives:
    """The validated drive file at ``path``.

    Raises:
        RobotFileError: no such file.
        ScenarioError: an invalid key (named, with the file and the allowed range).
    """
    if not Path(path).is_file():
        raise RobotFileError(f"the servo plant needs the robot's drive file {str(path)!r}, which does not exist")
    try:
        return load_table(Drives, path)
    except ScenarioError as exc:
        raise RobotFileError(str(exc)) from None


def drive_array(drives: Drives, *, gain_scale: float = 1.0, torque_limited: bool = True) -> Array:
    """The kernel's drive array (12, 4) in kernel order (mission joints 1-6, then balance).

    Columns: servo gain [N m s/rad] times ``gain_scale``, torque limit [N m] (inf when not
    ``torque_limited``), armature gear² · rotor inertia [kg m²], viscous friction [N m s/rad].
    """
    out = np.zeros((12, 4))
    for arm, drive in enumerate((drives.mission, drives.balance)):
        rows = slice(6 * arm, 6 * arm + 6)
        out[rows, 0] = np.array(drive.servo_gain_Nm_s_per_rad) * gain_scale
        out[rows, 1] = drive.torque_limit_Nm if torque_limited else np.inf
        out[rows, 2] = np.square(drive.gear_ratio) * np.array(drive.rotor_inertia_kg_m2)
        out[rows, 3] = drive.viscous_friction_Nm_s_per_rad
    return out
