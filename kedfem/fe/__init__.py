"""The finite-element wing: from a mechanism in motion to M, C, K and Q.

`assembly` (DOF numbering, constraint maps, scattering: `FEModel`), `effects` (the effect
registry, the `Assembler`, damping models), one module per plug-in effect (`joint_torque`),
`modal_damping`, `reduction` (Craig-Bampton).
"""
