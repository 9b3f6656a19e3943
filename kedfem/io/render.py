"""Off-screen PNG renders of an exported VTK frame with pyvista.

Headless rendering needs no display and no extra system packages with the
PyPI ``vtk`` wheel (9.3 or later): when no X display is available VTK falls
back to EGL, which Mesa provides in software (llvmpipe). To skip VTK's failed
attempt to open an X window, :func:`headless_environment` sets
``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` *before vtk is imported*
when neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` is set (an explicit value of
that variable is left alone). ``pyvista.start_xvfb`` no longer exists, and
forcing OSMesa (``vtkOSOpenGLRenderWindow``) crashes the PyPI wheel, so
neither is used. On a machine without ``libEGL``/``libGL`` (a very slim
container) install Mesa's ``libegl1`` and ``libgl1`` (Debian names).

The render reads the exported ``.vtu`` file back (what ParaView would see),
draws the undeformed configuration in light grey and the deformed one with
its links coloured by the nodal stress (or by the displacement magnitude when
no stress is known), bodies as translucent polygons.
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .export import atomic_path, require

__all__ = ["headless_environment", "render_frame", "render_series"]

log = logging.getLogger(__name__)


def headless_environment() -> bool:
    """Prepare VTK for off-screen rendering without a display.

    Returns True when no display is set (and, unless the user chose a render
    window class, selects EGL). Has an effect only before ``vtk`` is imported.
    """
    headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if headless:
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    return headless


def _pyvista():
    headless_environment()
    pv = require("pyvista", "render", "rendering")
    pv.OFF_SCREEN = True
    return pv


def render_frame(vtu, png, *, scalars: str | None = None, window_size=(1280, 800), line_width: float = 6.0,
                 title: str | None = None, undeformed: bool = True) -> Path:
    """Render one exported ``.vtu`` frame off-screen to a PNG.

    Parameters
    ----------
    vtu : str or Path
        A frame written by :func:`kedfem.io.export.write_vtk_series` (or a mode shape).
    png : str or Path
        Output image.
    scalars : str, optional
        Point data colouring the links (default ``nodal_stress`` when any is
        finite, else the magnitude of ``displacement``).
    window_size : (int, int)
        Image size [pixels].
    line_width : float
        Drawn line width [pixels].
    title : str, optional
        Text in the upper-left corner.
    undeformed : bool
        Also draw the rigid-body configuration (grey).

    Returns
    -------
    Path
    """
    vtu = Path(vtu)
    if not vtu.is_file():
        raise InputError(f"render: no such VTK file {vtu}")
    if vtu.suffix.lower() != ".vtu":
        raise InputError(f"render: {vtu} is not a .vtu frame: render_frame draws one frame of a series "
                         f"(e.g. response/response_0000.vtu); for a .pvd series use render_series, or "
                         f"`kedfem export --render --frame K`")
    pv = _pyvista()
    try:
        grid = pv.read(vtu)
    except Exception as e:  # noqa: BLE001 - a reader error on a damaged file
        raise InputError(f"render: cannot read {vtu} as an unstructured grid: {e}") from None
    if grid.n_points == 0:
        raise InputError(f"render: {vtu} has no points")
    scale = float(grid.field_data["scale"][0]) if "scale" in grid.field_data else 1.0
    disp = np.asarray(grid.point_data["displacement"]) if "displacement" in grid.point_data else None
    if scalars is None:
        st = grid.point_data.get("nodal_stress")
        if st is not None and np.isfinite(st).any():
            scalars, bar = "nodal_stress", "stress [Pa]"
        elif disp is not None:
            grid.point_data["displacement_magnitude"] = np.linalg.norm(disp, axis=1)
            scalars, bar = "displacement_magnitude", "elastic displacement [m]"
        else:
            bar = None
    else:
        if scalars not in grid.point_data:
            raise InputError(f"render: {vtu} has no point data {scalars!r} "
                             f"(available: {', '.join(grid.point_data.keys())})")
        bar = scalars
    celltypes = np.asarray(grid.celltypes)
    line_ids = np.flatnonzero(celltypes == pv.CellType.LINE)
    poly_ids = np.flatnonzero(celltypes != pv.CellType.LINE)
    pl = pv.Plotter(off_screen=True, window_size=tuple(int(w) for w in window_size))
    try:
        pl.set_background("white")
        if undeformed and disp is not None:
            ghost = grid.copy()
            ghost.points = grid.points - scale * disp
            pl.add_mesh(ghost.extract_cells(line_ids) if line_ids.size else ghost, color="#c8c8c8",
                        line_width=max(1.0, line_width / 2), render_lines_as_tubes=False)
        if poly_ids.size:
            pl.add_mesh(grid.extract_cells(poly_ids), color="#6a8caf", opacity=0.35, show_edges=True,
                        edge_color="#34495e", line_width=2)
        if line_ids.size:
            lines = grid.extract_cells(line_ids)
            kw = {}
            if scalars is not None:
                kw = dict(scalars=scalars, cmap="viridis", nan_color="#555555",
                          scalar_bar_args={"title": bar, "color": "black", "vertical": True,
                                           "fmt": "%.3g", "position_x": 0.86, "position_y": 0.15})
            pl.add_mesh(lines, line_width=line_width, render_lines_as_tubes=True, **kw)
        if title:
            pl.add_text(title, position="upper_left", font_size=10, color="black")
        pl.view_xy()
        pl.reset_camera()
        png = Path(png)
        with atomic_path(png) as tmp:
            pl.screenshot(str(tmp), transparent_background=False)
    finally:
        pl.close()
    log.info("rendered %s -> %s", vtu, png)
    return png


def render_series(series, png, *, frame: int | None = None, **kw) -> Path:
    """Render one frame of a written :class:`~kedfem.io.export.VtkSeries` (default: its peak frame)."""
    k = series.peak_frame if frame is None else int(frame)
    if not 0 <= k < len(series.files):
        raise InputError(f"render: frame must lie in 0..{len(series.files) - 1}, got {frame}")
    title = kw.pop("title", None)
    if title is None:
        t = float(series.times[k])
        title = f"t = {t:.4g} s, deformation x{series.scale:g}" if math.isfinite(t) else None
    return render_frame(series.files[k], png, title=title, **kw)
