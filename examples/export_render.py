"""Export the deformed mechanism over the cycle for ParaView and render a PNG off-screen.

Writes ``response/response.pvd`` (one ``.vtu`` per time node: links as polylines of their FE
nodes, point data ``displacement``, cell data ``axial_force``/``bending_moment``/``stress``),
``modes/modes.pvd`` (mode shapes) and ``deformed.png`` (pyvista, no display needed).
Run: ``python examples/export_render.py`` then open ``export-out/response/response.pvd`` in ParaView.
"""

from pathlib import Path

import kedfem as kf
import mechanisms
from kedfem.io import export, render


def main(out="export-out", steps=120, render_png=True):
    mech = mechanisms.build("exciter", eccentricity=0.01, spring=2.0e4)
    scene = kf.Scene(mech, steps=steps, effects=("inertia", "coupling", "springs"),
                     damping=kf.Rayleigh(alpha=0.0, beta=1e-4), name="exciter")
    res = kf.solve(scene)
    out = Path(out)
    series = export.write_vtk_series(res, out)               # deformation scale chosen automatically
    modes = export.write_mode_shapes(res, out, n_modes=3)
    print(f"{series.pvd}: {len(series.files)} frames, deformation x{series.scale:g}; {modes.pvd}")
    png = None
    if render_png:
        png = render.render_series(series, out / "deformed.png")  # the frame of largest displacement
        print(f"rendered {png}")
    return series, modes, png


if __name__ == "__main__":
    main()
