"""The motion wing: the rigid-body motion of a mechanism.

`kinematics` (loop closure, velocities and accelerations at any instants; `Cycle`, `Motion`),
`kinetostatics` (the rigid-body joint reactions and drive torque).
"""
