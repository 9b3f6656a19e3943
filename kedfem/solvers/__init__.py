"""The solvers wing: time discretisations and the periodic solve, independent of mechanisms.

`expm` and `split` (matrix exponentials per time element; `expm` draws on `balancing`,
`scaling_squaring` and `vanloan`), `collocation` (Radau IIA and Gauss; with `tableaux`,
`collocation_elements` and `collocation_residual`), `fourier` (whole-cycle Fourier collocation),
`schemes` (the method registry), `periodic` (the exponential holds' periodic solve and Floquet
multipliers; with `inputs`, `state_space` and `holds`), `cyclic` (the block-cyclic system the
one-step schemes share; with `condensation`, `monodromy`, `cyclic_lu` and `march`), `nonlinear`
(the fixed-point and Anderson iterations), `defect` (the defect-correction error estimate),
`eigen` (generalised symmetric eigenproblems), `parallel` (the worker threads), `threads` (the
BLAS thread policy).
"""
