"""The solvers wing: time discretisations and the periodic solve, independent of mechanisms.

`expm` and `split` (matrix exponentials per time element), `collocation` (Radau IIA and Gauss),
`fourier` (whole-cycle Fourier collocation), `schemes` (the method registry), `periodic` (the
block-cyclic periodic system and Floquet multipliers), `nonlinear` (the fixed-point and Anderson
iterations), `eigen` (generalised symmetric eigenproblems), `threads` (the BLAS thread policy).
"""
