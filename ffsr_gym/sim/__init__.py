"""Closed-loop simulation: the :class:`~ffsr_gym.sim.rollout.Rollout` interface, its reference (Pinocchio)
and compiled backends, the per-scenario set-up they share, :class:`Trajectory` and ``simulate``.

Imports ``model``, ``planning`` and ``kernel``.
"""
