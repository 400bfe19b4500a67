"""Scores computed from a :class:`~ffsr_gym.sim.trajectory.Trajectory`: the paper's objective B, feasibility
and the benchmark score. One code path for the env reward, the optimisers and the leaderboards.

Imports ``model`` and ``sim.trajectory``.
"""
