"""The lab: reference integrators and flop counts for tests and benchmarks.

Nothing in the core imports this package (a test keeps it so).
`transient`: direct time integration to the periodic state, the second method the periodic
solve is checked against and the peers of `benchmarks/peers.py` (Newmark average acceleration,
and scipy's Radau / DOP853): `integrate_periodic` on a callable system, `integrate_sampled` on
terms sampled over the cycle. `flops`: floating-point operation counts of the solvers.
"""
