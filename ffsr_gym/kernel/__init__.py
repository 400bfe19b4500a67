"""The compiled (numba) kernel: the planner and the physics of one step, the closed loop and its batched form.

The numba modules import only each other; ``arrays`` reads their inputs from ``model``.
"""
