"""The input/output wing: scene files, exports, plots, renders, sweeps and output folders.

`scenefile` (TOML scenes; the parser knows no mechanism), `export` (CSV, NPZ, VTK), `plots`,
`render` (pyvista, off-screen), `sweep` and `sweep_journal` (parameter sweeps, resumable),
`outdir` (an output folder published whole or not at all).
"""
