"""The finite-element wing: from a mechanism in motion to q-space M, C, K and Q.

`model` (`FEModel`: `dofs` numbering, `maps` constraint maps with `forms` (an entity's affine
form) and `slots` (blocks sliding on members), `scatter`), `structure` (element
matrices assembled in every scene), `effects/` (one module per effect and their registry),
`assembler` (structure + chosen effects at any instants, state terms), `damping` (Rayleigh,
modal), `modal_damping`, `reduction` (Craig-Bampton).
"""
