"""The kernel's Python face: the native kernel (C++17 in ``src/native``, compiled at install into
``ffsr_gym._native``) and what it is built from.

``arrays`` extracts the robot's numbers from its URDF through Pinocchio; ``robot`` makes the typed robot of them,
``planner`` the planner's settings of a scenario, ``layout`` names the state, log and decision layouts.
"""
