"""Version policy: which benchmark versions exist and which is ranked (above the model's data and scoring).

Imports ``model``.
"""
