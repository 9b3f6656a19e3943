"""The model wing: what a mechanism is made of.

`mechanism` (the builder, `Mechanism`: its members, springs, drives and loads), `components` (the
records it holds: joints, links, bodies, point masses, springs, drives, loads, friction),
`joints` (adding joints and placing them from lengths and angles), `queries` (what the other wings
ask a mechanism about its graph), `consistency` (`Mechanism.validate`), `arguments` (the builder's
shared argument checks), `placement` (the geometry of joint positions from link lengths),
`materials` (materials and cross-sections), `profiles` (process-load profiles over the cycle),
`elements` (the planar beam element's matrices).
"""
