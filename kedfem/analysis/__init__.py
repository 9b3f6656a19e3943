"""The analysis wing: scenes, the solve pipeline and what is read from a result.

`scene` (a validated scene), `pipeline` (`solve`: levels, iteration, estimate), `accuracy`
(error estimates and the stability verdict), `results` and `recovery` (deflections, section
forces, stresses, peaks), `modal`, `statics`, `mesh_check`, `validation`, `defaults`.
"""
