"""The ``ffsr-gym reproduce`` report: the paper's experiments, figures and the claims table.

Imports ``sim``, ``planning``, ``model`` and ``provenance``.
"""
