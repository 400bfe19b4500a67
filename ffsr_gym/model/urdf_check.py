"""A URDF read and checked as the file says, before Pinocchio sees it (docs/robots.md).

Pinocchio merges the links on fixed joints into their parents and recurses along the tree, so
what must hold of *every link of the file* is checked here, on the XML itself:

* the file is a regular file of at most :data:`MAX_URDF_BYTES`, without a DTD (no entities);
* at most :data:`MAX_LINKS` links, chains at most :data:`MAX_CHAIN` joints deep (a chain of
  thousands of fixed joints overflows the parser's recursion and kills the process);
* joints of the types the closed loop integrates (revolute, continuous, fixed), a revolute or
  continuous joint about a finite, non-zero axis;
* every link's mass finite and >= 0, with a rotational inertia positive definite and obeying the
  triangle inequality when it has mass (a massless link: zero inertia).

A continuous joint is a revolute joint without position limits (the benchmark never reads joint
limits: its limit is the joint rate), so it is handed to Pinocchio as revolute with unbounded
limits: one angle, like every other joint of the arms.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ffsr_gym.exceptions import FFSRError, RobotFileError
from ffsr_gym.user_files import read_text

#: The largest URDF read [bytes].
MAX_URDF_BYTES = 8 * 2**20
#: The most links a URDF may have.
MAX_LINKS = 1000
#: The deepest chain of joints from the root link.
MAX_CHAIN = 100
#: Joint types a robot may use (movable ones: revolute about a fixed axis).
JOINT_TYPES = ("revolute", "continuous", "fixed")
#: The limits a continuous joint gets as a revolute one [rad] (never read: only the rate is limited).
UNBOUNDED_RAD = 1e9


def read_urdf(path: Path) -> str:
    """The URDF's XML as Pinocchio should load it (continuous joints as unbounded revolute ones), checked.

    Raises:
        RobotFileError: what the file breaks, naming the file and the element.
    """
    try:
        text = read_text(path, max_bytes=MAX_URDF_BYTES)
    except FFSRError as exc:
        raise RobotFileError(f"robot file {exc}") from None
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise RobotFileError(f"{path}: a DTD or entity declaration; allowed: plain URDF XML (no <!DOCTYPE>, <!ENTITY>)")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotFileError(f"robot file {str(path)!r} could not be parsed: {exc}") from None
    links, joints = root.findall("link"), root.findall("joint")
    if len(links) > MAX_LINKS:
        raise RobotFileError(f"{path}: {len(links)} links; allowed: at most {MAX_LINKS}")
    _check_tree(path, links, joints)
    for joint in joints:
        _check_joint(path, joint)
    for link in links:
        _check_link(path, link)
    try:
        return ET.tostring(root, encoding="unicode")
    except RecursionError:
        raise RobotFileError(f"{path}: XML nested too deep; allowed: a URDF (links and joints under <robot>)") from None


def _check_tree(path: Path, links: list[ET.Element], joints: list[ET.Element]) -> None:
    """Each link has at most one parent joint, and no chain is deeper than :data:`MAX_CHAIN` (no recursion here)."""
    parent: dict[str, str] = {}
    for joint in joints:
        child, up = joint.find("child"), joint.find("parent")
        if child is None or up is None:
            raise RobotFileError(f"{path}: joint {joint.get('name')!r} lacks a <parent> or <child>")
        name = child.get("link", "")
        if name in parent:
            raise RobotFileError(f"{path}: link {name!r} is the child of two joints; allowed: a tree")
        parent[name] = up.get("link", "")
    depth: dict[str, int] = {}
    for link in (element.get("name", "") for element in links):
        chain, node = [], link
        while node in parent and node not in depth:
            chain.append(node)
            node = parent[node]
            if len(chain) > MAX_CHAIN:
                raise RobotFileError(f"{path}: a chain of more than {MAX_CHAIN} joints above link {link!r} (or a "
                                     f"loop); allowed: at most {MAX_CHAIN}")
        base = depth.get(node, 0)
        for k, name in enumerate(reversed(chain), start=1):
            depth[name] = base + k
            if depth[name] > MAX_CHAIN:
                raise RobotFileError(f"{path}: link {name!r} is {depth[name]} joints from the root; allowed: at most "
                                     f"{MAX_CHAIN}")


def _numbers(text: str | None, count: int) -> list[float] | None:
    try:
        values = [float(x) for x in (text or "").split()]
    except ValueError:
        return None
    return values if len(values) == count and all(math.isfinite(v) for v in values) else None


def _check_joint(path: Path, joint: ET.Element) -> None:
    name, kind = joint.get("name"), joint.get("type")
    if kind not in JOINT_TYPES:
        raise RobotFileError(f"{path}: joint {name!r} is of type {kind!r}; allowed: {list(JOINT_TYPES)}")
    if kind == "fixed":
        return
    axis = joint.find("axis")
    xyz = _numbers("1 0 0" if axis is None else axis.get("xyz"), 3)
    if xyz is None or math.hypot(*xyz) < 1e-9:
        raise RobotFileError(f"{path}: joint {name!r} has axis {None if axis is None else axis.get('xyz')!r}; "
                             "allowed: three finite numbers, not all zero (the joint turns about it)")
    if kind == "continuous":
        joint.set("type", "revolute")
        for old in joint.findall("limit"):
            joint.remove(old)
        ET.SubElement(joint, "limit", lower=str(-UNBOUNDED_RAD), upper=str(UNBOUNDED_RAD), effort="0", velocity="0")


def _check_link(path: Path, link: ET.Element) -> None:
    name, inertial = link.get("name"), link.find("inertial")
    if inertial is None:
        return  # a massless frame (Pinocchio merges it into its parent)
    mass_element, inertia = inertial.find("mass"), inertial.find("inertia")
    mass = _numbers(None if mass_element is None else mass_element.get("value"), 1)
    if mass is None or mass[0] < 0.0:
        raise RobotFileError(f"{path}: link {name!r} has mass "
                             f"{None if mass_element is None else mass_element.get('value')!r} kg; allowed: a finite "
                             "number >= 0")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    values = _numbers(" ".join(str(inertia.get(k, "0")) for k in keys) if inertia is not None else "0 0 0 0 0 0", 6)
    if values is None:
        raise RobotFileError(f"{path}: link {name!r}: inertia {keys} must be finite numbers [kg m²]")
    ixx, ixy, ixz, iyy, iyz, izz = values
    moments = np.linalg.eigvalsh(np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]))
    if mass[0] == 0.0:
        if np.any(moments != 0.0):
            raise RobotFileError(f"{path}: link {name!r} has no mass but a rotational inertia; allowed: both zero")
        return
    a, b, c = np.sort(moments)
    if a <= 0.0 or a + b < c * (1.0 - 1e-9):
        raise RobotFileError(f"{path}: link {name!r} has a rotational inertia with principal moments "
                             f"{np.round(moments, 9).tolist()} kg m²; allowed: positive definite, obeying the "
                             "triangle inequality")
