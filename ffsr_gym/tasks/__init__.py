"""Task generation: the random scenario family (and the benchmark's task tiers).

Imports ``model``, ``planning``, ``sim`` and ``scoring``.
"""
