"""The input/output wing: scene files, exports, plots, renders, sweeps and output folders.

`scenefile` (TOML scenes; the parser knows no mechanism) with `scene_values` (where a key is,
its checked value, the errors naming it), `report` (a result's folder and its summary; `digits`:
the digits a figure's error allows), `export` (CSV, NPZ, VTK), `fatigue_files` and
`loads_files` (the fatigue, history and load tables), `plots`, `render` (pyvista, off-screen),
`design_plots` (Campbell and stability-map tables and charts, `stability_map`), `branch_files`
(a continuation's tables, read back), `sweep` and `sweep_journal` (parameter sweeps, resumable),
`outdir` (an output folder published whole or not at all). Every CSV follows the one table
convention of docs/usage.md ("Tables").
"""
