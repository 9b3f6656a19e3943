"""Off-screen renders of exported VTK frames with pyvista: PNG frames and animated GIFs.

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

The render reads the exported ``.vtu`` file back (what ParaView would see)
and explains itself:

* the undeformed (rigid-body) configuration in light grey;
* the deformed links coloured by the nodal stress in MPa (or by the elastic
  displacement magnitude in mm when no stress is known; a mode shape by its
  dimensionless amplitude), rigid links, whose stress the model does not
  compute, in dark grey; bodies as translucent polygons;
* the symbols of the export's ``symbol`` points (:data:`kedfem.io.export.SYMBOLS`):
  revolute joints as white pins, grounds as dark triangles on a hatched base,
  clamped grounds as dark squares, welded joints as small dark squares,
  sliders as a box between two guide lines along the slider's axis,
  torsional springs as spirals; springs as zig-zag lines (to the frame: from
  a hatched anchor);
* a title with the crank angle [deg] and the deformation scale.

:func:`render_animation` writes the deformed cycle as an animated GIF
(Pillow) with one colour range and one camera for every frame.
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .export import PART_KINDS, SYMBOLS, atomic_path, require

__all__ = ["frame_scalars", "frame_title", "headless_environment", "render_animation", "render_frame",
           "render_series"]

log = logging.getLogger(__name__)

_INK = "#1b1b1b"        # symbol lines
_DARK = "#2c3e50"       # grounds, clamps, welds
_GHOST = "#c8c8c8"      # undeformed configuration
_NAN = "#555555"        # links without the coloured quantity (rigid links)
_SPRING_KINDS = (PART_KINDS["spring"], PART_KINDS["spring to frame"])
#: Radius of a joint symbol as a fraction of the drawing's diagonal.
_GLYPH_FRACTION = 0.011


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


def _read(vtu):
    """Read one exported frame (a pyvista grid), with the checks and errors of the renderers."""
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
    return grid


def _grid(frame):
    return _read(frame) if isinstance(frame, (str, os.PathLike)) else frame


def _field(grid, name: str):
    v = grid.field_data.get(name) if name in grid.field_data else None
    return float(v[0]) if v is not None and len(v) else None


def _masked(grid, name: str, flag: str) -> np.ndarray:
    """A point array as floats, NaN where its flag array says the model has no value."""
    a = np.asarray(grid.point_data[name], dtype=float)
    if a.ndim == 2:
        a = np.linalg.norm(a, axis=1)
    if flag in grid.point_data:
        a = np.where(np.asarray(grid.point_data[flag]) == 1, a, np.nan)
    return a


def frame_scalars(frame, scalars: str | None = None) -> tuple[np.ndarray | None, str | None]:
    """The values colouring the links of a frame, in the units of its colour bar.

    Parameters
    ----------
    frame : str, Path or pyvista.UnstructuredGrid
        An exported ``.vtu`` frame (or the grid read from one).
    scalars : str, optional
        Point data to colour by. Default: ``nodal_stress`` when the frame
        has stresses, else the magnitude of ``displacement``.

    Returns
    -------
    values : ndarray, shape (n_points,), or None
        One value per point, NaN where the model has none (rigid links for
        stresses and section forces) and at the symbols' points (joints,
        frame-spring anchors), which colour no link. ``nodal_stress`` in
        MPa (the file's Pa / 1e6), ``nodal_bending_moment`` in N m, an
        elastic displacement magnitude in mm (a mode shape's
        dimensionless), other arrays as stored (vectors: their magnitude).
        None when there is nothing to colour by.
    title : str or None
        The colour bar's title with the unit, e.g. ``"stress [MPa]"``.
    """
    grid = _grid(frame)
    values, title = _scalars(grid, scalars)
    if values is not None and "symbol" in grid.point_data:
        values = np.where(np.asarray(grid.point_data["symbol"]) > 0, np.nan, values)
    return values, title


def _scalars(grid, scalars):
    pd = grid.point_data
    mode = _field(grid, "mode") is not None
    if scalars is None:
        if "nodal_stress" in pd and np.isfinite(_masked(grid, "nodal_stress", "stress_computed")).any():
            scalars = "nodal_stress"
        elif "displacement" in pd:
            scalars = "displacement"
        else:
            return None, None
    elif scalars not in pd:
        raise InputError(f"render: the frame has no point data {scalars!r} "
                         f"(available: {', '.join(pd.keys())})")
    if scalars == "nodal_stress":
        return _masked(grid, scalars, "stress_computed") / 1e6, "stress [MPa]"
    if scalars == "nodal_bending_moment":
        return _masked(grid, scalars, "section_forces_computed"), "bending moment [N m]"
    if scalars == "displacement":
        d = _masked(grid, scalars, "")
        return (d, "mode shape [-]") if mode else (d * 1e3, "elastic displacement [mm]")
    return _masked(grid, scalars, ""), scalars


def frame_title(frame) -> str | None:
    """The default title of a frame, from its field data.

    ``"crank angle 123.4 deg, deformation x200"`` for a response frame (the
    crank angle modulo 360 deg), ``"mode 2: 41.7 Hz at crank angle 0.0 deg"``
    for a mode shape; None when the frame carries neither.
    """
    grid = _grid(frame)
    angle, scale = _field(grid, "crank_angle"), _field(grid, "scale")
    mode, freq = _field(grid, "mode"), _field(grid, "frequency")
    if mode is not None:
        head = f"mode {mode:g}" + (f": {freq:.4g} Hz" if freq is not None else "")
        at = _response_title(angle, None)
        return f"{head} at {at}" if at else head
    return _response_title(angle, scale)


def _response_title(angle: float | None, scale: float | None) -> str | None:
    """``"crank angle 123.4 deg, deformation x200"`` from an absolute crank angle [rad] (None: no title)."""
    if angle is None or not math.isfinite(angle):
        return None
    at = f"crank angle {round(math.degrees(angle) % 360.0, 1) % 360.0:.1f} deg"
    return f"{at}, deformation x{scale:g}" if scale is not None else at


# ------------------------------------------------------------------- symbols
class _Sketch:
    """Symbol geometry collected as white fills, dark fills and ink lines (three meshes in all)."""

    def __init__(self, r: float, z: float, rails: dict | None = None):
        self.r, self.z, self.rails = r, z, rails or {}
        self.white, self.dark, self.ink = [], [], []

    def circle(self, c, radius, n=24):
        a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
        return np.column_stack([c[0] + radius * np.cos(a), c[1] + radius * np.sin(a)])

    def pin(self, c, scale=1.0):
        ring = self.circle(c, scale * self.r)
        self.white.append(ring)
        self.ink.append(np.vstack([ring, ring[:1]]))

    def square(self, c, half, e=(1.0, 0.0), fill="dark", outline=False):
        e = np.asarray(e, float)
        nrm = np.array([-e[1], e[0]])
        h0, h1 = (half, half) if np.isscalar(half) else half
        box = np.array([c + s0 * h0 * e + s1 * h1 * nrm for s0, s1 in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        (self.dark if fill == "dark" else self.white).append(box)
        if outline:
            self.ink.append(np.vstack([box, box[:1]]))

    def hatch(self, c, e, half):
        """A ground line through ``c`` along ``e`` with strokes on the side opposite to ``n = rot90(e)``."""
        e = np.asarray(e, float)
        nrm = np.array([-e[1], e[0]])
        self.ink.append(np.array([c - half * e, c + half * e]))
        for s in np.linspace(-half, half * 0.6, 5):
            p = c + s * e
            self.ink.append(np.array([p, p - 0.7 * self.r * (nrm - e)]))

    def ground(self, c):
        r = self.r
        apex, base = np.asarray(c, float), np.asarray(c, float) + (0.0, -2.6 * r)
        self.dark.append(np.array([apex, base + (-1.5 * r, 0.0), base + (1.5 * r, 0.0)]))
        self.hatch(base, (1.0, 0.0), 2.1 * r)
        self.pin(c, 0.75)

    def slider(self, c, axis, rail=None):
        """A box along ``axis`` between two guide lines; ``rail`` = (lo, hi) travel along it [m]."""
        e = np.asarray(axis, float)
        e = e / (np.linalg.norm(e) or 1.0)
        nrm = np.array([-e[1], e[0]])
        self.square(c, (1.8 * self.r, 1.0 * self.r), e, fill="white", outline=True)
        t = float(c @ e)
        lo, hi = rail if rail is not None else (t, t)
        lo, hi = lo - t - 5.0 * self.r, hi - t + 5.0 * self.r
        for side in (-1.25, 1.25):
            q = c + side * self.r * nrm
            self.ink.append(np.array([q + lo * e, q + hi * e]))
        self.pin(c, 0.5)

    def spiral(self, c):
        a = np.linspace(0.0, 3.5 * math.pi, 48)
        rad = self.r * (1.4 + a / (3.5 * math.pi))
        self.ink.append(np.column_stack([c[0] + rad * np.cos(a), c[1] + rad * np.sin(a)]))

    def zigzag(self, p, q, waves=6):
        p, q = np.asarray(p, float), np.asarray(q, float)
        length = float(np.linalg.norm(q - p))
        if length == 0.0:
            return
        e = (q - p) / length
        nrm = np.array([-e[1], e[0]])
        amp = min(0.7 * self.r, 0.15 * length)
        s = np.linspace(0.2, 0.8, 2 * waves + 1)
        off = np.zeros_like(s)
        off[1:-1:2], off[2:-1:2] = amp, -amp
        mid = p + np.outer(s * length, e) + np.outer(off, nrm)
        self.ink.append(np.vstack([p, mid, q]))

    def meshes(self, pv):
        """(PolyData, colour, is_fill) of the non-empty buckets, at the symbol layer z."""
        out = []
        for shapes, colour, fill, dz in ((self.dark, _DARK, True, 0.0), (self.white, "white", True, 0.1),
                                         (self.ink, _INK, False, 0.2)):
            if not shapes:
                continue
            pts = np.vstack(shapes)
            pts3 = np.column_stack([pts, np.full(len(pts), self.z * (1.0 + dz))])
            conn, i = [], 0
            for sh in shapes:
                conn += [len(sh), *range(i, i + len(sh))]
                i += len(sh)
            out.append((pv.PolyData(pts3, faces=conn) if fill else pv.PolyData(pts3, lines=conn), colour, fill))
        return out


def _slider_axes(grid) -> dict:
    """Point index -> unit axis of the slider symbols of a frame."""
    pd = grid.point_data
    if "symbol" not in pd:
        return {}
    axis = np.asarray(pd["slider_axis"])[:, :2] if "slider_axis" in pd else np.zeros((grid.n_points, 2))
    out = {}
    for i in np.flatnonzero(np.asarray(pd["symbol"]) == SYMBOLS["slider"]):
        e = axis[i] if np.any(axis[i]) else np.array([1.0, 0.0])
        out[int(i)] = e / np.linalg.norm(e)
    return out


def _rails(grids) -> dict:
    """Point index -> (lo, hi) travel of each slider along its axis over the frames [m]."""
    axes = _slider_axes(grids[0])
    rails = {}
    for i, e in axes.items():
        t = [float(np.asarray(g.points)[i, :2] @ e) for g in grids if i < g.n_points]
        rails[i] = (min(t), max(t))
    return rails


def _sketch_symbols(grid, pv, r: float, z: float, rails: dict | None = None) -> _Sketch:
    sk = _Sketch(r, z, rails)
    pts = np.asarray(grid.points)[:, :2]
    pd = grid.point_data
    # springs first: their anchors need the direction of the spring
    if "part_kind" in grid.cell_data:
        kinds = np.asarray(grid.cell_data["part_kind"])
        sym = np.asarray(pd["symbol"]) if "symbol" in pd else np.zeros(grid.n_points, int)
        for c in np.flatnonzero(np.isin(kinds, _SPRING_KINDS)):
            ids = np.asarray(grid.get_cell(int(c)).point_ids)
            if ids.size != 2:
                continue
            a, b = ids
            if sym[b] == SYMBOLS["frame anchor"]:
                a, b = b, a
            sk.zigzag(pts[a], pts[b])
            if sym[a] == SYMBOLS["frame anchor"]:
                e = pts[b] - pts[a]
                e = e / (np.linalg.norm(e) or 1.0)
                sk.hatch(pts[a], (e[1], -e[0]), 1.6 * r)
    if "symbol" not in pd:
        return sk
    sym = np.asarray(pd["symbol"])
    axes = _slider_axes(grid)
    for i in np.flatnonzero(sym > 0):
        c, s = pts[i], int(sym[i])
        if s == SYMBOLS["revolute joint"]:
            sk.pin(c)
        elif s == SYMBOLS["welded joint"]:
            sk.square(c, 0.75 * r)
        elif s == SYMBOLS["ground"]:
            sk.ground(c)
        elif s == SYMBOLS["clamped ground"]:
            sk.square(c, 1.3 * r)
        elif s == SYMBOLS["slider"]:
            sk.slider(c, axes[int(i)], sk.rails.get(int(i)))
        elif s == SYMBOLS["torsional spring"]:
            sk.spiral(c)
    return sk


# -------------------------------------------------------------------- frames
def _extent(grid, undeformed: bool) -> np.ndarray:
    """Rectangle [xmin, xmax, ymin, ymax] of the deformed (and undeformed) points [m]."""
    pts = np.asarray(grid.points)[:, :2]
    if undeformed and "displacement" in grid.point_data:
        scale = _field(grid, "scale") or 1.0
        pts = np.vstack([pts, pts - scale * np.asarray(grid.point_data["displacement"])[:, :2]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return np.array([lo[0], hi[0], lo[1], hi[1]])


def _layout(extent: np.ndarray):
    """Glyph radius, symbol depth and padded view rectangle of a drawing of the given extent."""
    diag = float(math.hypot(extent[1] - extent[0], extent[3] - extent[2])) or 1.0
    r = _GLYPH_FRACTION * diag
    pad = 8.0 * r
    return r, 0.01 * diag, (extent[0] - pad, extent[1] + pad, extent[2] - pad, extent[3] + pad)


def _draw(pl, pv, grid, *, values, bar, clim, title, undeformed, line_width, layout, rails=None):
    """Add one frame's actors to the plotter ``pl``."""
    r, z, _view = layout
    celltypes = np.asarray(grid.celltypes)
    kinds = np.asarray(grid.cell_data["part_kind"]) if "part_kind" in grid.cell_data else np.zeros(celltypes.size)
    is_line = celltypes == pv.CellType.LINE
    spring = np.isin(kinds, _SPRING_KINDS)
    line_ids = np.flatnonzero(is_line & ~spring)
    poly_ids = np.flatnonzero(~is_line & ~spring)
    disp = np.asarray(grid.point_data["displacement"]) if "displacement" in grid.point_data else None
    scale = _field(grid, "scale") or 1.0
    if undeformed and disp is not None and line_ids.size:
        ghost = grid.extract_cells(line_ids).copy(deep=True)     # extract_cells shares the frame's points
        g_disp = np.asarray(ghost.point_data["displacement"])
        ghost.points = np.asarray(ghost.points) - scale * g_disp - (0.0, 0.0, z)
        pl.add_mesh(ghost, color=_GHOST, line_width=max(1.0, line_width / 2), render_lines_as_tubes=False,
                    render=False)
    if poly_ids.size:
        body = grid.extract_cells(poly_ids).copy(deep=True)
        body.points = np.asarray(body.points) - (0.0, 0.0, 0.5 * z)
        pl.add_mesh(body, color="#6a8caf", opacity=0.35, show_edges=True, edge_color="#34495e", line_width=2,
                    render=False)
    if line_ids.size:
        kw = {}
        if values is not None and np.isfinite(values).any():
            grid.point_data["_colour"] = values
            kw = {"scalars": "_colour", "cmap": "viridis", "nan_color": _NAN, "clim": clim,
                  "scalar_bar_args": {"title": bar, "color": "black", "vertical": True, "fmt": "%.3g",
                                      "position_x": 0.86, "position_y": 0.15}}
        lines = grid.extract_cells(line_ids)
        pl.add_mesh(lines, line_width=line_width, render_lines_as_tubes=True, color=_NAN, render=False, **kw)
    for mesh, colour, fill in _sketch_symbols(grid, pv, r, z, rails).meshes(pv):
        pl.add_mesh(mesh, color=colour, line_width=max(1.0, line_width / 3), lighting=not fill, render=False)
    if title:
        pl.add_text(title, position="upper_left", font_size=10, color="black", render=False)


def _frame_clim(values):
    finite = values[np.isfinite(values)] if values is not None else np.empty(0)
    if finite.size == 0:
        return None
    lo, hi = float(finite.min()), float(finite.max())
    return (lo, hi) if hi > lo else (lo - 0.5 * (abs(lo) or 1.0), hi + 0.5 * (abs(hi) or 1.0))


def _camera(pl, view):
    """A fixed top view of the rectangle ``view`` (parallel projection)."""
    x0, x1, y0, y1 = view
    w, h = pl.window_size
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    half_height = max(0.5 * (y1 - y0), 0.5 * (x1 - x0) * h / w / 0.8)   # the colour bar takes the right fifth
    dist = 10.0 * max(x1 - x0, y1 - y0, 1e-9)
    pl.enable_parallel_projection()
    pl.camera_position = [(cx + 0.08 * half_height * w / h, cy, dist), (cx + 0.08 * half_height * w / h, cy, 0.0),
                          (0.0, 1.0, 0.0)]
    pl.camera.parallel_scale = 1.05 * half_height
    pl.camera.clipping_range = (0.5 * dist, 1.5 * dist)


def _plotter(pv, window_size):
    size = tuple(int(w) for w in window_size)
    if len(size) != 2 or min(size) < 16:
        raise InputError(f"render: window_size must be two sizes >= 16 [pixels], got {window_size!r}")
    pl = pv.Plotter(off_screen=True, window_size=size)
    pl.set_background("white")
    return pl


def render_frame(vtu, png, *, scalars: str | None = None, window_size=(1280, 800), line_width: float = 6.0,
                 title: str | None = None, undeformed: bool = True, clim=None) -> Path:
    """Render one exported ``.vtu`` frame off-screen to a PNG.

    Parameters
    ----------
    vtu : str or Path
        A frame written by :func:`kedfem.io.export.write_vtk_series` (or a mode shape).
    png : str or Path
        Output image (written atomically).
    scalars : str, optional
        Point data colouring the links (see :func:`frame_scalars`; default:
        the nodal stress [MPa] when the frame has any, else the elastic
        displacement magnitude [mm]).
    window_size : (int, int)
        Image size [pixels].
    line_width : float
        Drawn line width of the links [pixels].
    title : str, optional
        Text in the upper-left corner; default :func:`frame_title` (crank
        angle [deg] and deformation scale), ``""`` for none.
    undeformed : bool
        Also draw the rigid-body configuration (grey).
    clim : (float, float), optional
        Colour range in the colour bar's units (default: the frame's range).

    Returns
    -------
    Path
    """
    grid = _read(vtu)
    pv = _pyvista()
    values, bar = frame_scalars(grid, scalars)
    title = frame_title(grid) if title is None else title
    extent = _extent(grid, undeformed)
    layout = _layout(extent)
    pl = _plotter(pv, window_size)
    try:
        _draw(pl, pv, grid, values=values, bar=bar, clim=_frame_clim(values) if clim is None else tuple(clim),
              title=title, undeformed=undeformed, line_width=line_width, layout=layout)
        _camera(pl, layout[2])
        png = Path(png)
        with atomic_path(png) as tmp:
            pl.screenshot(str(tmp), transparent_background=False)
    finally:
        pl.close()
    log.info("rendered %s -> %s", vtu, png)
    return png


def _series_title(series, k: int) -> str | None:
    """The title of file ``k`` of a series from its crank angles (None: render_frame reads the file's)."""
    angles = getattr(series, "crank_angles", None)
    return None if angles is None else _response_title(float(angles[k]), series.scale)


def render_series(series, png, *, frame: int | None = None, **kw) -> Path:
    """Render one frame of a written :class:`~kedfem.io.export.VtkSeries` to a PNG.

    Parameters
    ----------
    series : VtkSeries
    png : str or Path
        Output image.
    frame : int, optional
        Position in ``series.files`` (default: ``series.peak_frame``, the
        frame of the largest elastic displacement).
    **kw
        Passed on to :func:`render_frame`; the default title names the
        frame's crank angle [deg] and the deformation scale.

    Returns
    -------
    Path
    """
    k = series.peak_frame if frame is None else int(frame)
    if not 0 <= k < len(series.files):
        raise InputError(f"render: frame must lie in 0..{len(series.files) - 1}, got {frame}")
    if kw.get("title") is None:
        kw["title"] = _series_title(series, k)
    return render_frame(series.files[k], png, **kw)


def _frame_indices(series, frames, max_frames: int) -> list[int]:
    n = len(series.files)
    if frames is None:
        if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) or max_frames < 1:
            raise InputError(f"render_animation: max_frames must be an integer >= 1, got {max_frames!r}")
        return list(range(0, n, max(1, math.ceil(n / max_frames))))
    try:
        ks = [int(k) for k in frames]
    except (TypeError, ValueError):
        raise InputError(f"render_animation: frames must be positions in series.files, got {frames!r}") from None
    bad = [k for k in ks if not 0 <= k < n]
    if not ks or bad:
        raise InputError(f"render_animation: frames must be a non-empty list of positions in 0..{n - 1}"
                         + (f", got {bad[:5]}" if bad else ""))
    return ks


def render_animation(series, path, *, frames=None, fps: float = 12.0, max_frames: int = 60,
                     scalars: str | None = None, clim=None, window_size=(800, 500), line_width: float = 4.0,
                     undeformed: bool = True, loop: bool = True) -> Path:
    """Render the frames of a written series off-screen into an animated GIF.

    Every frame is drawn as by :func:`render_frame` (symbols, colour bar,
    title with the crank angle), with one colour range (by default the
    smallest and largest value over every file of the series, the whole
    written cycle) and one camera (framing all rendered frames), so the
    colours and the picture compare from frame to frame. The frames share
    one 256-colour palette. The GIF is written with Pillow, atomically.

    Parameters
    ----------
    series : VtkSeries
        From :func:`kedfem.io.export.write_vtk_series`.
    path : str or Path
        Output ``.gif``.
    frames : sequence of int, optional
        Positions in ``series.files`` to render, in order. Default: every
        ``k``-th file, ``k`` the smallest giving at most ``max_frames``.
    fps : float
        Frames per second of the animation [1/s] (0.5 to 50; GIF stores
        the frame duration in 10 ms steps).
    max_frames : int
        Most frames rendered by default.
    scalars : str, optional
        Point data colouring the links (:func:`frame_scalars`).
    clim : (float, float), optional
        Colour range in the colour bar's units (e.g. MPa), instead of the
        series' range.
    window_size : (int, int)
        Image size [pixels].
    line_width : float
        Drawn line width of the links [pixels].
    undeformed : bool
        Also draw the rigid-body configuration (grey).
    loop : bool
        Repeat the animation endlessly (else play it once).

    Returns
    -------
    Path
    """
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0.5 <= fps <= 50:
        raise InputError(f"render_animation: fps must be a number in 0.5..50 [1/s], got {fps!r}")
    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise InputError(f"render_animation: writes an animated GIF, the path must end in .gif, got {path}")
    ks = _frame_indices(series, frames, max_frames)
    image = require("PIL.Image", None, "the animated GIF")
    pv = _pyvista()
    grids = [_read(series.files[k]) for k in ks]
    coloured = [frame_scalars(g, scalars) for g in grids]
    clim = _series_clim(series, scalars, dict(zip(ks, coloured))) if clim is None else tuple(clim)
    ext = np.array([_extent(g, undeformed) for g in grids])
    layout = _layout(np.array([ext[:, 0].min(), ext[:, 1].max(), ext[:, 2].min(), ext[:, 3].max()]))
    rails = _rails(grids)
    pictures = []
    pl = _plotter(pv, window_size)
    try:
        for i, (k, g, (values, bar)) in enumerate(zip(ks, grids, coloured)):
            pl.clear_actors()
            for title_ in list(pl.scalar_bars.keys()):
                pl.remove_scalar_bar(title_, render=False)
            title = _series_title(series, k) or frame_title(g)
            _draw(pl, pv, g, values=values, bar=bar, clim=clim, title=title, undeformed=undeformed,
                  line_width=line_width, layout=layout, rails=rails)
            if i == 0:
                _camera(pl, layout[2])
            pl.render()          # the screenshot alone would not redraw the replaced actors
            pictures.append(image.fromarray(np.asarray(pl.screenshot(None, return_img=True))[..., :3]))
    finally:
        pl.close()
    gif = _gif_frames(image, pictures)
    repeat = {"loop": 0} if loop else {}
    with atomic_path(path) as tmp:
        gif[0].save(tmp, format="GIF", save_all=True, append_images=gif[1:], duration=round(1000.0 / fps),
                    optimize=False, disposal=1, **repeat)
    log.info("rendered %d frames of %s -> %s", len(gif), series.pvd, path)
    return path


def _series_clim(series, scalars, known: dict):
    """Smallest and largest colour value over every file of the series (``known``: values already read)."""
    lo, hi = math.inf, -math.inf
    for k, f in enumerate(series.files):
        values = known[k][0] if k in known else frame_scalars(_read(f), scalars)[0]
        if values is not None and np.isfinite(values).any():
            lo, hi = min(lo, float(np.nanmin(values))), max(hi, float(np.nanmax(values)))
    return _frame_clim(np.array([lo, hi])) if lo <= hi else None


def _gif_frames(image, pictures):
    """The pictures on one shared 256-colour palette (from a thumbnail strip of all of them)."""
    w, h = pictures[0].size
    step = max(1, math.ceil(len(pictures) / 16))
    thumbs = pictures[::step]
    strip = image.new("RGB", (w, h * len(thumbs)))
    for i, p in enumerate(thumbs):
        strip.paste(p, (0, i * h))
    palette = strip.quantize(colors=255, method=image.Quantize.MEDIANCUT)
    out = [p.quantize(palette=palette, dither=image.Dither.NONE) for p in pictures]
    # the background's entry is the median of white and its near-white antialiasing: make it white again
    background = int(np.bincount(np.asarray(out[0]).ravel()).argmax())
    rgb = out[0].getpalette()
    rgb[3 * background:3 * background + 3] = [255, 255, 255]
    for p in out:
        p.putpalette(rgb)
    return out
