"""Searches over planner parameters and policies: the paper's GA, its study report, and RL training.

Imports ``bench`` and below.
"""
