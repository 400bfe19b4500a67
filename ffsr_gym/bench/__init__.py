"""The benchmark around the environments: ``evaluate``, the evaluation protocol and the leaderboards.

Imports ``environments``, ``scoring``, ``tasks`` and below.
"""
