"""Renders that explain themselves: the exported frames carry the joints, grounds, sliders and
springs; the render draws them, colours in MPa (mm), names the crank angle; the cycle as a GIF."""

import math
import warnings

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.io import export

pv = pytest.importorskip("pyvista")
render = pytest.importorskip("kedfem.io.render")
Image = pytest.importorskip("PIL.Image")


@pytest.fixture(scope="module")
def res():
    """The brief's small slider-crank, with a spring between joints, one to the frame and a torsional one."""
    m = mechanisms.build("slider_crank", elements=2)
    m.spring("tie", "A", "B", k=1e3, axis=(1.0, 0.0))
    m.spring("return", "B", k=1e3, axis=(1.0, 0.0))
    m.torsional_spring("coil", "A", "crank", "rod", k=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")           # 24 fixed time elements: accuracy warnings
        return kf.solve(kf.Scene(m, steps=24, effects=("inertia", "coupling", "springs"),
                                 damping=kf.ModalDamping(0.02)))


@pytest.fixture(scope="module")
def series(res, tmp_path_factory):
    return export.write_vtk_series(res, tmp_path_factory.mktemp("vtk"), every=6, scale=20.0)


@pytest.fixture(scope="module")
def can_render(series, tmp_path_factory):
    try:
        render.render_frame(series.files[0], tmp_path_factory.mktemp("probe") / "probe.png", window_size=(64, 64))
    except kf.OptionalDependencyError as e:
        pytest.skip(f"rendering needs an optional package: {e}")
    except Exception as e:  # noqa: BLE001 - no OpenGL / EGL on this machine
        pytest.skip(f"off-screen rendering impossible here: {type(e).__name__}: {e}")


class Captured:
    """Records the meshes and texts a render adds (the plotter itself is closed on return)."""

    def __init__(self, monkeypatch):
        self.meshes, self.texts = [], []
        real_mesh, real_text = pv.Plotter.add_mesh, pv.Plotter.add_text

        def add_mesh(pl, mesh, *a, **kw):
            self.meshes.append((mesh.copy(), kw))
            return real_mesh(pl, mesh, *a, **kw)

        def add_text(pl, text, *a, **kw):
            self.texts.append(text)
            return real_text(pl, text, *a, **kw)

        monkeypatch.setattr(pv.Plotter, "add_mesh", add_mesh)
        monkeypatch.setattr(pv.Plotter, "add_text", add_text)

    def coloured(self):
        return [(m, kw) for m, kw in self.meshes if "scalar_bar_args" in kw]


def test_the_frames_carry_joints_grounds_sliders_and_springs(res, series):
    mech = res.model.mech
    g = pv.read(series.files[2])
    k = series.frames[2]
    sym = np.asarray(g.point_data["symbol"])
    joints = list(mech.joints.values())
    expected = {"ground": sum(j.kind == "ground" and not j.welded for j in joints),
                "slider": sum(j.kind == "slider" for j in joints),
                "revolute joint": sum(j.kind == "revolute" and not j.welded for j in joints),
                "torsional spring": len(mech.torsional_springs),
                "frame anchor": sum(s.b is None for s in mech.springs.values())}
    assert expected == {"ground": 1, "slider": 1, "revolute joint": 1, "torsional spring": 1, "frame anchor": 1}
    for name, count in expected.items():
        assert (sym == export.SYMBOLS[name]).sum() == count, name
    # each joint's symbol point sits at its deformed place: rigid + scale * elastic, and carries its data
    part = next(p for p in series.parts if p.kind == "joints")
    assert part.cells.start == part.cells.stop            # points only: every cell stays a line
    assert set(np.asarray(g.celltypes)) == {pv.CellType.LINE}
    for i, j in enumerate(joints):
        p = part.points.start + i
        assert sym[p] == {"ground": export.SYMBOLS["ground"], "slider": export.SYMBOLS["slider"],
                          "revolute": export.SYMBOLS["revolute joint"]}[j.kind]
        np.testing.assert_allclose(g.points[p, :2], res.motion.position(j.name)[k]
                                   + 20.0 * res.joint_displacement(j.name)[k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(g.point_data["displacement"][p, :2], res.joint_displacement(j.name)[k],
                                   atol=1e-15)
        axis = g.point_data["slider_axis"][p, :2]
        np.testing.assert_array_equal(axis, j.axis if j.kind == "slider" else (0.0, 0.0))
    # springs: one line per spring, marked by part_kind; the frame spring from its fixed anchor
    kinds = np.asarray(g.cell_data["part_kind"])
    assert (kinds == export.PART_KINDS["spring"]).sum() == sum(s.b is not None for s in mech.springs.values())
    assert (kinds == export.PART_KINDS["spring to frame"]).sum() == 1
    assert (kinds == export.PART_KINDS["flexible link"]).sum() == mech.links["rod"].elements
    assert (kinds == export.PART_KINDS["rigid link"]).sum() == 1
    ret = next(p for p in series.parts if p.name == "return")
    assert ret.kind == "spring to frame" and sym[ret.points.start] == export.SYMBOLS["frame anchor"]
    anchors = [pv.read(f).points[ret.points.start] for f in series.files[:3]]
    np.testing.assert_allclose(anchors[0], anchors[2], rtol=0, atol=1e-15)  # fixed: B moves along the axis
    for f in series.files[::7]:  # the spring is drawn along its axis, whichever way its joint moves
        pts = pv.read(f).points
        d = pts[ret.points.start + 1, :2] - pts[ret.points.start, :2]
        ax = np.asarray(mech.springs["return"].axis, float)
        assert abs(d[0] * ax[1] - d[1] * ax[0]) <= 1e-12 * np.linalg.norm(d)
    np.testing.assert_allclose(g.points[ret.points.start + 1], g.points[part.points.start + 2])  # at B
    text = series.pvd.read_text()
    assert "part_kind: 1 = flexible link" in text and "symbol (points in no cell): 1 = revolute joint" in text


def test_symbols_leave_the_scale_and_the_member_data_alone(res):
    mesh = export.mechanism_mesh(res)
    members = [p for p in mesh.parts if p.kind in ("flexible link", "rigid link", "body", "spring")]
    last = max(p.points.stop for p in members)
    assert all(p.points.start >= last for p in mesh.parts if p not in members)     # appended after the members
    bare = export.MechanismMesh(tuple(members), mesh.rigid[:, :last], mesh.displacement[:, :last], (), {}, {})
    assert export.auto_scale(mesh) == export.auto_scale(bare)


def test_crank_angles_in_the_series_and_the_title(res, series, can_render, tmp_path, monkeypatch):
    np.testing.assert_array_equal(series.crank_angles, res.crank_angle[series.frames])
    np.testing.assert_array_equal(pv.get_reader(str(series.pvd)).time_values, res.t[series.frames])  # unchanged
    k = 7
    deg = math.degrees(res.crank_angle[series.frames[k]]) % 360
    expected = f"crank angle {deg:.1f} deg, deformation x20"
    assert render.frame_title(series.files[k]) == expected
    cap = Captured(monkeypatch)
    render.render_series(series, tmp_path / "f.png", frame=k, window_size=(320, 200))
    assert cap.texts == [expected]
    modes = export.write_mode_shapes(res, tmp_path, n_modes=2)
    np.testing.assert_array_equal(modes.crank_angles, [res.crank_angle[0]] * 2)
    assert render.frame_title(modes.files[1]).startswith("mode 2: ")


def test_colours_in_mpa_and_mm(series, can_render, tmp_path, monkeypatch):
    g = pv.read(series.files[3])
    values, title = render.frame_scalars(g)
    assert title == "stress [MPa]"
    ok = (np.asarray(g.point_data["stress_computed"]) == 1) & (np.asarray(g.point_data["symbol"]) == 0)
    assert ok.sum() >= 3
    np.testing.assert_allclose(values[ok], np.asarray(g.point_data["nodal_stress"])[ok] / 1e6, rtol=1e-15)
    assert np.isnan(values[~ok]).all()              # rigid links and symbols: no stress, drawn in grey
    d, title = render.frame_scalars(g, "displacement")
    assert title == "elastic displacement [mm]"
    np.testing.assert_allclose(d[ok], np.linalg.norm(g.point_data["displacement"], axis=1)[ok] * 1e3, rtol=1e-15)
    with pytest.raises(kf.InputError, match="no point data 'nope'"):
        render.frame_scalars(g, "nope")
    # what the render hands to pyvista: the MPa values under the MPa colour bar
    cap = Captured(monkeypatch)
    png = render.render_frame(series.files[3], tmp_path / "s.png", window_size=(480, 300))
    (mesh, kw), = cap.coloured()
    assert kw["scalar_bar_args"]["title"] == "stress [MPa]"
    lines = np.asarray(mesh["_colour"])
    ids = np.asarray(mesh["vtkOriginalPointIds"])
    np.testing.assert_array_equal(mesh.points, g.points[ids])     # the deformed frame, not the grey one under it
    ghost = next(m for m, kw in cap.meshes if kw.get("color") == "#c8c8c8")
    assert np.abs(ghost.points[:, :2] - mesh.points[:, :2]).max() > 1e-4
    assert np.nanmax(lines) == pytest.approx(np.nanmax(values), rel=1e-15)
    assert kw["clim"] == (np.nanmin(values), np.nanmax(values))
    # the symbols are drawn: dark fills (the ground), white fills (pins, slider box), ink lines (springs)
    colours = {kw.get("color") for m, kw in cap.meshes if isinstance(m, pv.PolyData)}
    assert {"#2c3e50", "white", "#1b1b1b"} <= colours
    ink = next(m for m, kw in cap.meshes if isinstance(m, pv.PolyData) and kw.get("color") == "#1b1b1b")
    assert ink.n_lines >= 2 + 2 + 1 + 1                  # two zig-zags, two slider guides, a spiral, a hatch
    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape == (300, 480, 3) and (img < 60).all(axis=-1).mean() > 0.001   # ink on the picture


def test_animated_gif_of_the_cycle(series, can_render, tmp_path, monkeypatch):
    n = len(series.files)
    cap = Captured(monkeypatch)
    gif = render.render_animation(series, tmp_path / "cycle.gif", max_frames=6, window_size=(320, 200), fps=10)
    step = math.ceil(n / 6)
    expected = len(range(0, n, step))
    with Image.open(gif) as im:
        assert im.n_frames == expected and im.size == (320, 200)
        frames = []
        for i in (0, expected // 2):
            im.seek(i)
            frames.append(np.asarray(im.convert("RGB")).astype(int))
        assert im.info["duration"] == 100
    assert np.abs(frames[0] - frames[1]).sum(axis=-1).astype(bool).mean() > 0.002   # the mechanism moves
    assert (frames[0][-1, 0] == 255).all()                                            # on a white background
    # one colour range for all frames: the whole written cycle's
    clims = {kw["clim"] for _, kw in cap.coloured()}
    values = np.concatenate([render.frame_scalars(f)[0] for f in series.files])
    assert clims == {(np.nanmin(values), np.nanmax(values))}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cycle.gif"]               # no temporary left
    assert cap.texts[0].startswith("crank angle 0.0 deg")


def test_animation_arguments_are_checked_and_a_failure_keeps_the_old_gif(series, can_render, tmp_path,
                                                                          monkeypatch):
    with pytest.raises(kf.InputError, match=r"\.gif"):
        render.render_animation(series, tmp_path / "cycle.png")
    with pytest.raises(kf.InputError, match="frames"):
        render.render_animation(series, tmp_path / "c.gif", frames=[0, 999])
    with pytest.raises(kf.InputError, match="fps"):
        render.render_animation(series, tmp_path / "c.gif", fps=0)
    old = tmp_path / "c.gif"
    old.write_bytes(b"old")

    def full(*a, **kw):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Image.Image, "save", full)
    with pytest.raises(OSError, match="No space"):
        render.render_animation(series, old, frames=[0, 1], window_size=(64, 64))
    assert old.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["c.gif"]


def test_a_vertical_frame_spring_on_a_joint_moving_sideways_is_drawn_vertical(tmp_path):
    """A spring to the frame acts along its axis: drawn along it at every frame, from an anchor
    that keeps its station on the axis (a fixed anchor drew it as a diagonal)."""
    m = kf.Mechanism("crank on a vertical spring")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(0.1, 0.0))
    m.link("crank", "O", "A", material=kf.Material(E=2e11, rho=7850.0), section=kf.Section.rectangle(0.01, 0.01),
           elements=2)
    m.spring("lift", "A", k=1e3, axis=(0.0, 1.0))
    m.drive("crank", speed=10.0)
    r = kf.solve(kf.Scene(m, steps=24, estimate=False, effects=("inertia", "coupling", "springs")))
    s = export.write_vtk_series(r, tmp_path)
    sp = next(p for p in s.parts if p.name == "lift")
    xs = []
    for f in s.files:
        pts = pv.read(f).points
        a, b = pts[sp.points.start, :2], pts[sp.points.start + 1, :2]
        assert abs(a[0] - b[0]) <= 1e-12 and b[1] > a[1]  # vertical, the anchor below the joint
        xs.append(a[0])
    assert max(xs) - min(xs) > 0.1  # the joint went round: the spring moved sideways with it
