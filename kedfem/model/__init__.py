"""The model wing: what a mechanism is made of.

`mechanism` (links, joints, drives, bodies, springs, loads, the builder), `materials` (materials
and cross-sections), `elements` (the planar beam element's matrices), `topology` (the compiled,
read-only view of a mechanism that the other wings query).
"""
