"""The planner's equations in readable numpy: predefined-time function, pose errors, desired path,
danger-field avoidance, singularity-robust inverse and the four planning methods.

Imports ``model`` only. This is the reference the compiled kernel is validated against.
"""
