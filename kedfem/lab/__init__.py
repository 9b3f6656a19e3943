"""The lab: reference integrators and flop counts for tests and benchmarks.

Nothing in the core imports this package. `transient` (Newmark and Radau direct time
integration, the second method the periodic solve is checked against), `flops`.
"""
