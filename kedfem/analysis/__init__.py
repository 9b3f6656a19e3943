"""The analysis wing: scenes, the solve pipeline and what is read from a result.

`scene` (a validated scene), `pipeline` (`solve`: levels, iteration, estimate; its parts in
`resolution`, `stability_floor`, `forecast`, `level_estimates`, `homotopy`), `accuracy`
(error estimates and the stability verdict), `results` and `recovery` (deflections, section
forces, stresses, peaks; the result's read-outs in `displacements`, `section_forces`,
`block_forces`, `peak_refinement`, `peak_search`, `stations`), `hooks` (the io wing's writers,
handed over without importing it), `modal`, `statics`, `mesh_check`, `validation`, `defaults`.
"""
