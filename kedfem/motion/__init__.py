"""The motion wing: the rigid-body motion of a mechanism.

`kinematics` (loop closure, velocities and accelerations at any instants; `Cycle`, and the
positions by continuation), with `record` (the `Motion` record), `loops` (the loop-closure model:
tree, loops, residuals, Jacobian) and `rates` (the velocity and acceleration equations);
`kinetostatics` (the rigid-body joint reactions and drive torque); `stroke` (a reciprocating
joint's stroke and time ratio), `profiles` (a process load's factor over a motion), `crank` (the
crank angle's convention in words).
"""
