"""The robot and its world as data: scenarios (TOML), the Pinocchio robot, collision geometry, quaternions.

Imports nothing else of the project but ``exceptions`` and ``types``.
"""
