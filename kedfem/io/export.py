"""Exports of a periodic result: CSV tables, an NPZ archive and a VTK/PVD series for ParaView.

Every file is written atomically: to a temporary name in the target folder,
then moved into place with :func:`os.replace`. A VTK series is written into
a temporary folder that replaces the old series only when every frame has
been written, and its ``.pvd`` index is written last; an interrupted or
failed export leaves the previous output (or nothing) behind, never a
half-written series.

VTK layout (one ``.vtu`` per written time node, 3-D points with ``z = 0``):

* flexible links: one line cell per frame element between consecutive FE
  nodes (together a polyline of the link's nodes);
* rigid links: one line between their joints; bodies: a polygon through their
  joints (a line for two joints); springs between two joints: a line;
  springs to the frame: a line along the spring's axis to the joint from an
  anchor point behind it (8 % of the mechanism's size behind the joint's
  lowest station along the axis);
* joints and torsional springs: one extra point each, after the points of
  the parts and in no cell (so every cell stays a line or polygon), marked
  by the point data ``symbol`` (:data:`SYMBOLS`); the renderer draws them,
  ParaView shows them with *Glyph* (masked on ``symbol > 0``);
* points: rigid-body position plus ``scale`` times the elastic displacement;
* point data: ``displacement`` (elastic, 3-vector, [m], unscaled),
  ``position`` (total position, rigid + elastic, [m]),
  ``nodal_bending_moment`` [N m] and ``nodal_stress`` [Pa]; ``symbol``
  (int, 0 on the points of the parts) and ``slider_axis`` (unit direction
  of a slider's line at its symbol point, 0 elsewhere);
* cell data: ``axial_force`` [N], ``bending_moment`` [N m] (mean of the
  element's end nodes), ``stress`` [Pa] (larger of the end nodes),
  ``part_id`` and ``part_kind`` (:data:`PART_KINDS`);
* field data: ``time`` [s], ``crank_angle`` [rad], ``scale``, ``frame``.

Rigid parts and springs carry **NaN** section forces and stresses: the model
does not compute them (they are not zero), and ParaView draws NaN in its
"NaN colour", so they are not mistaken for unloaded links. The same for
flexible links whose section has no extreme-fibre distance ``c`` (stress).
The ``.pvd`` file lists the part ids and the codes of ``part_kind`` and
``symbol`` in a comment.

meshio, matplotlib and pyvista are imported lazily, inside the functions
that need them.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import importlib
import logging
import math
import os
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..errors import InputError, KedError, OptionalDependencyError
from ..motion.crank import crank_angle_convention

__all__ = ["OptionalDependencyError", "require", "atomic_path", "write_response_csv", "write_peaks_csv",
           "write_frequencies_csv", "column", "FREQUENCY_COLUMNS", "write_npz", "Part", "MechanismMesh", "mechanism_mesh", "auto_scale",
           "VtkSeries", "write_vtk_series", "write_mode_shapes", "dof_unit", "PART_KINDS", "SYMBOLS"]

log = logging.getLogger(__name__)


def require(module: str, extra: str | None = None, purpose: str = ""):
    """Import an optional module or raise :class:`OptionalDependencyError` with the install command."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        hint = f"pip install 'kedfem[{extra}]'" if extra else f"pip install {module.split('.')[0]}"
        raise OptionalDependencyError(f"{purpose or module} needs {module.split('.')[0]} ({hint}): {e}") from None


# ----------------------------------------------------------------- atomicity
def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.stem}.tmp-{os.getpid()}-{secrets.token_hex(3)}{path.suffix}")


@contextlib.contextmanager
def atomic_path(path):
    """Context manager yielding a temporary path that replaces ``path`` on success.

    The temporary file lives in the same folder (same file system, so the
    final :func:`os.replace` is atomic) and keeps the suffix (libraries that
    infer the format from it keep working). On an exception it is removed and
    ``path`` is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _fmt(x, missing: str = "") -> str:
    """Full-precision cell; ``missing`` for NaN (no NaN is written to a file)."""
    x = float(x)
    return missing if math.isnan(x) else repr(x)


def column(name: str, unit: str) -> str:
    """A table column's name with its SI unit as a suffix (the convention of every CSV kedfem
    writes, docs/usage.md "Tables"): ``column("peak_stress", "Pa") == "peak_stress_Pa"``; the
    unit's spaces and powers become underscores (``N m`` -> ``N_m``, ``kg^0.5 m`` -> ``kg0.5_m``);
    a dimensionless quantity (``unit`` empty) keeps its name."""
    if not unit:
        return name
    return f"{name}_{unit.replace('^', '').replace(' ', '_').replace('/', '_')}"


def dof_unit(label: str) -> str:
    """SI unit of a DOF label: ``m`` (translations), ``rad`` (rotations) or
    ``kg^0.5 m`` (mass-normalised modal coordinates ``etaK`` of reduced links)."""
    last = label.rsplit(".", 1)[-1].split("@")[0]
    if last in ("theta", "phi"):
        return "rad"
    if last.startswith("eta"):
        return "kg^0.5 m"
    return "m"


# ---------------------------------------------------------------------- CSV
def write_response_csv(res, path) -> Path:
    """Elastic displacements over the cycle: one row per time node.

    Columns ``t_s``, ``crank_angle_rad``, then every DOF label with its unit as a suffix
    (``_m`` or ``_rad``; the table convention of docs/usage.md). Numbers are written with full
    precision.
    """
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "crank_angle_rad"] + [column(d, dof_unit(d)) for d in res.dof_labels])
        for k in range(res.n):
            w.writerow([_fmt(res.t[k]), _fmt(res.crank_angle[k])] + [_fmt(x) for x in res.U[k]])
    return path


PEAK_COLUMNS = ("link", "peak_deflection_m", "deflection_angle_rad", "peak_stress_Pa",
                "stress_angle_rad", "stress_station_m", "deflection_time_error",
                "stress_time_error", "deflection_mesh_error", "stress_mesh_error")


def write_peaks_csv(res, path, peaks=None, mesh=None) -> Path:
    """Peak mid-span deflection and stress per flexible link (:meth:`PeriodicResult.peaks`).

    With the estimated relative errors of each peak: of the time discretisation
    (``res.error``) and of the mesh (``mesh``, a :class:`kedfem.analysis.mesh_check.MeshError`);
    empty where not estimated.
    """
    path = Path(path)
    peaks = res.peaks() if peaks is None else peaks

    def opt(x):
        return "" if x is None else _fmt(x)

    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(PEAK_COLUMNS)
        for p in peaks:
            te = res.error.link(p.link) if res.error is not None else None
            me = mesh.link(p.link) if mesh is not None else None
            w.writerow([p.link, _fmt(p.deflection), _fmt(p.deflection_angle), _fmt(p.stress),
                        _fmt(p.stress_angle), _fmt(p.stress_station),
                        opt(te.deflection if te else None), opt(te.stress if te else None),
                        opt(me.deflection if me else None), opt(me.stress if me else None)])
    return path


FREQUENCY_COLUMNS = ("crank_angle_rad", "mode", "modal_Hz", "state_space_Hz", "damping_ratio", "oscillating")


def write_frequencies_csv(freqs, path) -> Path:
    """Natural frequencies over the cycle (:class:`~kedfem.analysis.results.Frequencies`), tidy:
    one row per time node and mode.

    Columns :data:`FREQUENCY_COLUMNS`: ``crank_angle_rad``, ``mode`` (1..), ``modal_Hz``,
    ``state_space_Hz``, ``damping_ratio``, ``oscillating``. Where fewer than ``mode`` state-space
    eigenvalues oscillate (an overdamped mode), ``oscillating`` is ``False`` and the state-space
    frequency and damping cells are empty (no NaN is written).
    """
    path = Path(path)
    k = freqs.modal.shape[1]
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FREQUENCY_COLUMNS)
        for i in range(freqs.crank_angle.size):
            for j in range(k):
                fs, zr = freqs.state_space[i, j], freqs.damping_ratio[i, j]
                w.writerow([_fmt(freqs.crank_angle[i]), j + 1, _fmt(freqs.modal[i, j]), _fmt(fs), _fmt(zr),
                            not (math.isnan(float(fs)) or math.isnan(float(zr)))])
    return path


def write_npz(res, path, freqs=None) -> Path:
    """Compressed NumPy archive of the response (SI units).

    Arrays: ``t``, ``crank_angle`` (with ``crank_angle_convention``, its convention in
    words), ``U``, ``V``, ``dof_labels``,
    ``floquet_multipliers``, ``stable``, ``converged``, ``iterations``,
    ``history``, ``residual``, and with ``freqs`` the ``modal``,
    ``state_space`` and ``damping_ratio`` frequencies with the mask
    ``oscillating`` (False: a mode without oscillation, its two entries 0; no
    NaN is written) at the crank angles ``frequency_crank_angle`` (the frequencies are
    evaluated on a subset of the time nodes).
    """
    path = Path(path)
    arrays = dict(t=res.t, crank_angle=res.crank_angle,
                  crank_angle_convention=np.array(crank_angle_convention(res.model.mech)), U=res.U, V=res.V,
                  dof_labels=np.array(res.dof_labels, dtype=str),
                  floquet_multipliers=res.floquet_multipliers, stable=np.bool_(res.stable),
                  converged=np.bool_(res.converged), iterations=np.int64(res.iterations),
                  history=np.array(res.history, float), residual=np.float64(res.residual))
    if freqs is not None:
        osc = np.isfinite(freqs.state_space)
        arrays.update(frequency_crank_angle=freqs.crank_angle, modal=freqs.modal,
                      state_space=np.where(osc, freqs.state_space, 0.0),
                      damping_ratio=np.where(osc, freqs.damping_ratio, 0.0), oscillating=osc)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)
    return path


# --------------------------------------------------------------------- mesh
@dataclass(frozen=True)
class Part:
    """One drawn part of the mechanism mesh.

    ``points`` and ``cells`` are slices into the mesh's point and (global)
    cell order.
    """

    name: str
    kind: str            # a key of PART_KINDS, or "joints" / "torsional springs" (points only, no cells)
    part_id: int
    points: slice
    cells: slice


@dataclass(frozen=True)
class MechanismMesh:
    """The mechanism as a line/polygon mesh at every time node.

    Attributes
    ----------
    parts : tuple of Part
    rigid : ndarray, shape (n, P, 2)
        Rigid-body positions of the points [m].
    displacement : ndarray, shape (n, P, 2)
        Elastic displacements [m] (or a dimensionless mode shape).
    cells : tuple of (str, ndarray)
        Cells in global order: ``("line", (2,))`` or ``("polygon", (k,))`` connectivity.
    point_scalars : dict of str to ndarray, shape (n, P) or (n, P, 3)
        Includes the int ``symbol`` and the ``slider_axis`` vectors.
    cell_scalars : dict of str to ndarray, shape (n, C)
        Includes the int ``part_id`` and ``part_kind``.
    """

    parts: tuple[Part, ...]
    rigid: np.ndarray
    displacement: np.ndarray
    cells: tuple[tuple[str, np.ndarray], ...]
    point_scalars: dict
    cell_scalars: dict

    def part(self, name: str) -> Part:
        for p in self.parts:
            if p.name == name:
                return p
        raise InputError(f"no part '{name}' in the mesh (parts: {', '.join(p.name for p in self.parts)})")


#: Cell data ``part_kind``: what a cell belongs to.
PART_KINDS = {"flexible link": 1, "rigid link": 2, "body": 3, "spring": 4, "spring to frame": 5}

#: Point data ``symbol``: what the renderer draws at a point (0: a point of a part, nothing).
SYMBOLS = {"revolute joint": 1, "welded joint": 2, "ground": 3, "clamped ground": 4, "slider": 5,
           "torsional spring": 6, "frame anchor": 7}

#: Parts drawn as members (links, bodies, springs between joints): they set the deformation scale.
_MEMBER_KINDS = ("flexible link", "rigid link", "body", "spring")

#: Distance of a frame spring's anchor behind its joint, as a fraction of the mechanism's size.
_ANCHOR_FRACTION = 0.08


def _joint_symbol(joint) -> int:
    if joint.kind == "ground":
        return SYMBOLS["clamped ground" if joint.clamped else "ground"]
    if joint.kind == "slider":
        return SYMBOLS["slider"]
    return SYMBOLS["welded joint" if joint.welded else "revolute joint"]


def _legend(codes: dict) -> str:
    return ", ".join(f"{v} = {k}" for k, v in codes.items())


def _polygon_order(points: np.ndarray) -> np.ndarray:
    c = points.mean(axis=0)
    return np.argsort(np.arctan2(points[:, 1] - c[1], points[:, 0] - c[0]))


def mechanism_mesh(res, U: np.ndarray | None = None) -> MechanismMesh:
    """Build the mechanism's mesh over the cycle from a result.

    Parameters
    ----------
    res : PeriodicResult
    U : ndarray, shape (n, N) or (N,), optional
        A different DOF history (e.g. a mode shape) to map instead of the
        response; section forces are then NaN, and prescribed elastic parts
        (clamped ends, passive-link stretch) are not added.

    Returns
    -------
    MechanismMesh
    """
    mech = res.model.mech
    motion = res.motion
    n = res.n
    if U is not None:
        U = np.broadcast_to(np.asarray(U, float), res.U.shape)

    def jdisp(j):
        return res.joint_displacement(j, U=U)

    X, D, Pm, Ps, Sym = [], [], [], [], []
    cells, cAx, cM, cS, cPart = [], [], [], [], []
    parts = []
    npts = 0

    def add(name, kind, x0, d, pm=None, ps=None, conn=(), ax=None, symbol=None):
        nonlocal npts
        P = x0.shape[1]
        X.append(x0)
        D.append(d)
        Sym.append(np.zeros(P, dtype=np.int32) if symbol is None else np.asarray(symbol, dtype=np.int32))
        Pm.append(pm if pm is not None else np.full((n, P), np.nan))
        Ps.append(ps if ps is not None else np.full((n, P), np.nan))
        c0 = len(cells)
        for j, (typ, idx) in enumerate(conn):
            cells.append((typ, np.asarray(idx, dtype=np.int64) + npts))
            cAx.append(ax[:, j] if ax is not None else np.full(n, np.nan))
            ends = list(idx)
            pmv = Pm[-1][:, ends]
            psv = Ps[-1][:, ends]
            cM.append(pmv.mean(axis=1))
            cS.append(np.max(psv, axis=1) if not np.all(np.isnan(psv)) else np.full(n, np.nan))
            cPart.append(len(parts))
        parts.append(Part(name, kind, len(parts), slice(npts, npts + P), slice(c0, len(cells))))
        npts += P

    def jpos(j):
        return motion.position(j)

    for lk in mech.links.values():
        if lk.rigid:
            x0 = np.stack([jpos(lk.a), jpos(lk.b)], axis=1)
            d = np.stack([jdisp(lk.a), jdisp(lk.b)], axis=1)
            add(lk.name, "rigid link", x0, d, conn=[("line", (0, 1))])
        else:
            x0 = res.link_geometry(lk.name)
            d = res.link_displacement(lk.name) if U is None else res.link_displacement(lk.name, U=U)
            pm = ps = ax = None
            if U is None:
                pm = res.bending_moment(lk.name)
                ax = res.axial_force(lk.name)
                if lk.section.c is not None:
                    ps = res.stress(lk.name)
            conn = [("line", (e, e + 1)) for e in range(lk.elements)]
            add(lk.name, "flexible link", x0, d, pm, ps, conn, ax)
    for body in mech.bodies.values():
        js = list(body.joints)
        if len(js) < 2:
            continue
        ref = np.array([mech.joints[j].at for j in js], float)
        js = [js[i] for i in _polygon_order(ref)] if len(js) > 2 else js
        x0 = np.stack([jpos(j) for j in js], axis=1)
        d = np.stack([jdisp(j) for j in js], axis=1)
        conn = [("polygon", tuple(range(len(js))))] if len(js) > 2 else [("line", (0, 1))]
        add(body.name, "body", x0, d, conn=conn)
    for sp in mech.springs.values():
        if sp.b is None:
            continue
        x0 = np.stack([jpos(sp.a), jpos(sp.b)], axis=1)
        d = np.stack([jdisp(sp.a), jdisp(sp.b)], axis=1)
        add(sp.name, "spring", x0, d, conn=[("line", (0, 1))])
    if not parts:
        raise InputError(f"mechanism '{mech.name}' has nothing to draw")
    # the symbols, after the members (their point and cell indices stay as they were)
    r = np.concatenate(X, axis=1).reshape(-1, 2)
    size = float(np.linalg.norm(r.max(axis=0) - r.min(axis=0))) or 1.0
    for sp in mech.springs.values():
        if sp.b is not None:
            continue
        pa, axis = jpos(sp.a), np.asarray(sp.axis, float)
        s = pa @ axis
        # behind the joint along the spring's axis, at a fixed station of it: the spring is drawn
        # along its axis whichever way the joint moves across it (a fixed anchor tilted a vertical
        # spring on a joint that moves sideways into a diagonal)
        anchor = pa + ((s.min() - _ANCHOR_FRACTION * size) - s)[:, None] * axis
        x0 = np.stack([anchor, pa], axis=1)
        dj = jdisp(sp.a)
        d = np.stack([dj - (dj @ axis)[:, None] * axis, dj], axis=1)  # the anchor follows it across the axis
        add(sp.name, "spring to frame", x0, d, conn=[("line", (0, 1))], symbol=(SYMBOLS["frame anchor"], 0))
    js = list(mech.joints.values())
    add("joints", "joints", np.stack([jpos(j.name) for j in js], axis=1),
        np.stack([jdisp(j.name) for j in js], axis=1), symbol=[_joint_symbol(j) for j in js])
    ts = list(mech.torsional_springs.values())
    if ts:
        add("torsional springs", "torsional springs", np.stack([jpos(t.joint) for t in ts], axis=1),
            np.stack([jdisp(t.joint) for t in ts], axis=1), symbol=[SYMBOLS["torsional spring"]] * len(ts))
    sym = np.concatenate(Sym)
    slider_axis = np.zeros((sym.size, 3))
    joints_part = next(p for p in parts if p.kind == "joints")
    for i, j in enumerate(js):
        if j.kind == "slider":
            slider_axis[joints_part.points.start + i, :2] = j.axis
    C = len(cells)
    P = sym.size
    part_kind = np.array([PART_KINDS[parts[i].kind] for i in cPart], dtype=np.int32)
    return MechanismMesh(
        tuple(parts), np.concatenate(X, axis=1), np.concatenate(D, axis=1), tuple(cells),
        {"nodal_bending_moment": np.concatenate(Pm, axis=1), "nodal_stress": np.concatenate(Ps, axis=1),
         "symbol": np.broadcast_to(sym, (n, P)), "slider_axis": np.broadcast_to(slider_axis, (n, P, 3))},
        {"axial_force": np.stack(cAx, axis=1).reshape(n, C), "bending_moment": np.stack(cM, axis=1).reshape(n, C),
         "stress": np.stack(cS, axis=1).reshape(n, C),
         "part_id": np.broadcast_to(np.array(cPart, dtype=np.int64), (n, C)),
         "part_kind": np.broadcast_to(part_kind, (n, C))})


def _nice(x: float) -> float:
    """Largest 1, 2 or 5 times a power of ten not above ``x``."""
    e = math.floor(math.log10(x))
    m = x / 10**e
    return (5 if m >= 5 else 2 if m >= 2 else 1) * 10.0**e


def _member_points(mesh: MechanismMesh) -> np.ndarray:
    """Indices of the points of the members (all points when no part is a member)."""
    idx = [np.arange(p.points.start, p.points.stop) for p in mesh.parts if p.kind in _MEMBER_KINDS]
    return np.concatenate(idx) if idx else np.arange(mesh.rigid.shape[1])


def auto_scale(mesh: MechanismMesh, fraction: float = 0.05) -> float:
    """Deformation scale that makes the largest displacement ``fraction`` of the mechanism's size.

    The size is the diagonal of the bounding box of the rigid-body motion
    over the cycle. The scale is rounded down to 1, 2 or 5 times a power of
    ten, and never below 1 (deflections already that large are drawn true).
    Only the members count (links, bodies, springs between joints): the
    symbols' points (joints, frame-spring anchors) change neither.
    """
    idx = _member_points(mesh)
    dmax = float(np.max(np.linalg.norm(mesh.displacement[:, idx], axis=-1)))
    r = mesh.rigid[:, idx].reshape(-1, 2)
    size = float(np.linalg.norm(r.max(axis=0) - r.min(axis=0)))
    if not (dmax > 0 and size > 0 and math.isfinite(dmax)):
        return 1.0
    return max(1.0, _nice(fraction * size / dmax))


def _meshio_cells(mesh: MechanismMesh):
    """Group consecutive cells of the same type and size into meshio blocks."""
    blocks = []  # (type, [conn...], [global indices])
    for i, (typ, conn) in enumerate(mesh.cells):
        if blocks and blocks[-1][0] == typ and len(blocks[-1][1][0]) == len(conn):
            blocks[-1][1].append(conn)
            blocks[-1][2].append(i)
        else:
            blocks.append((typ, [conn], [i]))
    return [(t, np.array(c, dtype=np.int64)) for t, c, _ in blocks], [np.array(ix) for _, _, ix in blocks]


def _pad3(a2: np.ndarray) -> np.ndarray:
    out = np.zeros(a2.shape[:-1] + (3,))
    out[..., :2] = a2
    return out


def _field_xml(field: dict) -> str:
    out = ["<FieldData>"]
    for name, v in field.items():
        arr = np.atleast_1d(np.asarray(v, dtype=float))
        vals = " ".join(repr(float(x)) for x in arr)
        out.append(f'<DataArray type="Float64" Name={quoteattr(name)} NumberOfTuples="{arr.size}" '
                   f'format="ascii">{vals}</DataArray>')
    out.append("</FieldData>")
    return "\n".join(out)


def _write_vtu(path: Path, mesh_obj, field: dict | None = None) -> None:
    """Write one meshio mesh as VTU, with VTK field data (a separate function so tests can make it fail).

    meshio 5.3 does not write field data to VTU, so the ``<FieldData>``
    block (ASCII, one ``Float64`` array per entry) is inserted after the
    ``<UnstructuredGrid>`` tag of the written file.
    """
    import meshio
    meshio.write(path, mesh_obj, file_format="vtu")
    if field:
        text = Path(path).read_bytes()
        tag = b"<UnstructuredGrid>"
        i = text.find(tag)
        if i < 0:
            raise KedError(f"unexpected VTU layout written by meshio in {path}")
        i += len(tag)
        Path(path).write_bytes(text[:i] + b"\n" + _field_xml(field).encode() + text[i:])


def _frame_mesh(mesh: MechanismMesh, k: int, scale: float, field: dict, blocks, block_idx,
                point_extra: dict | None = None):
    import meshio
    pts = _pad3(mesh.rigid[k] + scale * mesh.displacement[k])
    point_data = {"displacement": _pad3(mesh.displacement[k]),
                  "position": _pad3(mesh.rigid[k] + mesh.displacement[k])}
    for name, arr in mesh.point_scalars.items():
        a = _finite(np.asarray(arr[k], dtype=float), name, point_data)
        if a is not None:
            point_data[name] = a
    if point_extra:
        point_data.update(point_extra)
    cells = {}
    for name, arr in mesh.cell_scalars.items():
        a = _finite(np.asarray(arr[k]), name, cells)
        if a is not None:
            cells[name] = a
    cell_data = {name: [np.ascontiguousarray(a[ix]) for ix in block_idx] for name, a in cells.items()}
    return meshio.Mesh(pts, blocks, point_data=point_data, cell_data=cell_data), field


#: The flag array that says where a section-force array holds values (1) and where
#: its member has none (0: rigid members, links without an extreme-fibre distance).
_COMPUTED = {"nodal_bending_moment": "section_forces_computed", "bending_moment": "section_forces_computed",
             "axial_force": "section_forces_computed", "nodal_stress": "stress_computed",
             "stress": "stress_computed"}


def _finite(a: np.ndarray, name: str, data: dict):
    """No NaN in a file: an array with no values is left out; missing values are 0 with a flag array."""
    if a.dtype.kind != "f":
        return np.ascontiguousarray(a)
    nan = np.isnan(a)
    if nan.all():
        return None
    flag = _COMPUTED.get(name)
    if flag is not None:
        data[flag] = (~nan).astype(np.int32) if flag not in data else data[flag] & (~nan).astype(np.int32)
    return np.ascontiguousarray(np.where(nan, 0.0, a))


@dataclass(frozen=True)
class VtkSeries:
    """A written VTK series.

    Attributes
    ----------
    pvd : Path
        The ParaView collection file.
    files : tuple of Path
        The ``.vtu`` files, in order.
    times : ndarray
        Their ``timestep`` values in the ``.pvd`` (time [s], or the mode
        number for mode shapes).
    frames : ndarray of int
        Time-node indices written (mode shapes: the time node of the modes).
    scale : float
        Deformation scale of the points.
    parts : tuple of Part
    peak_frame : int
        Position in ``files`` of the frame with the largest elastic displacement.
    crank_angles : ndarray, optional
        Crank angle of each file [rad], absolute (as
        :attr:`PeriodicResult.crank_angle`; mode shapes: that of their time
        node). None for a series described without them.
    """

    pvd: Path
    files: tuple[Path, ...]
    times: np.ndarray
    frames: np.ndarray
    scale: float
    parts: tuple[Part, ...]
    peak_frame: int
    crank_angles: np.ndarray | None = None


def _pvd_text(entries, comment: str) -> str:
    bo = "LittleEndian" if np.little_endian else "BigEndian"
    lines = ['<?xml version="1.0"?>', f'<VTKFile type="Collection" version="0.1" byte_order="{bo}">',
             f"  <!-- {comment.replace('--', '- -')} -->", "  <Collection>"]
    for t, rel in entries:
        lines.append(f'    <DataSet timestep="{float(t)!r}" group="" part="0" file={quoteattr(rel)}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    return "\n".join(lines)


def _check_stem(stem: str) -> str:
    if not stem or any(c in stem for c in "/\\\0") or stem.startswith("."):
        raise InputError(f"export: stem must be a plain file name, got {stem!r}")
    return stem


def _write_series(out_dir: Path, stem: str, frames_iter, entries_times, comment: str) -> tuple[Path, list[Path]]:
    """Write a series as one unit: the folder ``out_dir/stem/`` with ``stem.pvd`` and the frames.

    ``frames_iter`` yields ``(file name, (meshio mesh, field data))``. The
    folder is written beside its final place and published in one step
    (:func:`kedfem.io.outdir.publish_dir`), so a kill leaves the complete old
    series or the complete new one, its index always naming its own frames.
    """
    from .outdir import clean_leftovers, publish_dir
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    final = out_dir / stem
    if final.exists() and not final.is_dir():
        raise InputError(f"export: {final} is a file, not a folder")
    clean_leftovers(final)
    tmp = out_dir / f".{stem}.staging-{os.getpid()}-{secrets.token_hex(3)}"
    names = []
    try:
        tmp.mkdir()
        for fname, (m, field) in frames_iter:
            _write_vtu(tmp / fname, m, field)
            names.append(fname)
        (tmp / f"{stem}.pvd").write_text(_pvd_text(list(zip(entries_times, names)), comment))
        legacy = out_dir / f"{stem}.pvd"  # the index beside the folder of earlier versions
        if legacy.is_file():
            legacy.unlink()
        publish_dir(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final / f"{stem}.pvd", [final / nm for nm in names]


def _parts_comment(mesh: MechanismMesh, what: str) -> str:
    ids = "; ".join(f"{p.part_id} = {p.name} ({p.kind})" for p in mesh.parts if p.cells.stop > p.cells.start)
    return (f"kedfem {what}. part_id: {ids}. part_kind: {_legend(PART_KINDS)}. "
            f"symbol (points in no cell): {_legend(SYMBOLS)}")


def write_vtk_series(res, out_dir, *, stem: str = "response", scale: float | None = None,
                     every: int = 1) -> VtkSeries:
    """Write the deformed mechanism over the cycle as a ``.pvd`` collection of ``.vtu`` files.

    Parameters
    ----------
    res : PeriodicResult
    out_dir : str or Path
        Folder receiving the series folder ``<stem>/`` with its index
        ``<stem>.pvd`` and the frames ``<stem>_0000.vtu`` ... (replaced whole).
    stem : str
        Base name.
    scale : float, optional
        Deformation scale of the points (default :func:`auto_scale`); the
        point data are always unscaled.
    every : int
        Write every ``every``-th time node.

    Returns
    -------
    VtkSeries
    """
    _check_stem(stem)
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise InputError(f"write_vtk_series: every must be an integer >= 1, got {every!r}")
    if scale is not None and not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise InputError(f"write_vtk_series: scale must be a finite number > 0, got {scale!r}")
    require("meshio", None, "VTK export")
    mesh = mechanism_mesh(res)
    scale = auto_scale(mesh) if scale is None else float(scale)
    frames = np.arange(0, res.n, int(every))
    blocks, block_idx = _meshio_cells(mesh)
    width = max(4, len(str(res.n - 1)))

    def gen():
        for k in frames:
            field = {"time": res.t[k], "crank_angle": res.crank_angle[k], "scale": scale, "frame": k}
            yield f"{stem}_{k:0{width}d}.vtu", _frame_mesh(mesh, int(k), scale, field, blocks, block_idx)

    comment = _parts_comment(mesh, f"response of '{res.model.mech.name}', timestep = time [s], "
                                   f"deformation scale {scale:g}")
    pvd, files = _write_series(Path(out_dir), stem, gen(), res.t[frames], comment)
    dnorm = np.linalg.norm(mesh.displacement[frames], axis=-1).max(axis=1)
    log.info("wrote %s (%d frames, scale %g)", pvd, len(files), scale)
    return VtkSeries(pvd, tuple(files), res.t[frames].copy(), frames, scale, mesh.parts, int(np.argmax(dnorm)),
                     np.asarray(res.crank_angle, float)[frames].copy())


def write_mode_shapes(res, out_dir, *, n_modes: int = 4, node: int = 0, stem: str = "modes",
                      scale: float | None = None) -> VtkSeries:
    """Write mode shapes at one time node as their own ``.vtu`` files and a ``.pvd`` index.

    Each mode shape (:meth:`PeriodicResult.mode_shapes`) is normalised so its
    largest nodal translation is 1; ``displacement`` holds that dimensionless
    shape, the points are the rigid-body configuration plus ``scale`` times it
    (default: 10 % of the mechanism's size). In the ``.pvd`` the timestep is
    the mode number, so ParaView's time control steps through the modes;
    field data ``frequency`` [Hz] and ``mode`` identify each file.

    Returns
    -------
    VtkSeries
        ``times`` are the mode numbers 1..k.
    """
    _check_stem(stem)
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise InputError(f"write_mode_shapes: n_modes must be an integer >= 1, got {n_modes!r}")
    require("meshio", None, "VTK export")
    f, phi = res.mode_shapes(node=node, n_modes=int(n_modes))
    base = mechanism_mesh(res, U=np.zeros(res.U.shape[1]))
    r = base.rigid[node]
    size = float(np.linalg.norm(r.max(axis=0) - r.min(axis=0))) or 1.0
    s = 0.1 * size if scale is None else float(scale)
    meshes = []
    for j in range(phi.shape[1]):
        m = mechanism_mesh(res, U=phi[:, j])
        dmax = float(np.max(np.linalg.norm(m.displacement[node], axis=-1)))
        if dmax > 0:
            m = dataclasses.replace(m, displacement=m.displacement / dmax)
        meshes.append(m)
    blocks, block_idx = _meshio_cells(base)

    def gen():
        for j, m in enumerate(meshes):
            field = {"time": res.t[node], "crank_angle": res.crank_angle[node], "scale": s, "frame": node,
                     "mode": j + 1, "frequency": f[j]}
            yield f"mode_{j + 1:02d}.vtu", _frame_mesh(m, node, s, field, blocks, block_idx)

    comment = _parts_comment(base, f"mode shapes of '{res.model.mech.name}' at time node {node}, "
                                   "timestep = mode number; frequencies [Hz]: "
                                   + ", ".join(f"{x:.6g}" for x in f))
    modes = np.arange(1, phi.shape[1] + 1, dtype=float)
    pvd, files = _write_series(Path(out_dir), stem, gen(), modes, comment)
    return VtkSeries(pvd, tuple(files), modes, np.full(len(files), node), s, base.parts, 0,
                     np.full(len(files), float(res.crank_angle[node])))
