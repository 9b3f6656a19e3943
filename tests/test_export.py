"""CSV/NPZ/VTK exports read back equal the result; writes are atomic; the off-screen render is not blank."""

import csv
import os
import subprocess
import sys

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.io import export

pv = pytest.importorskip("pyvista")


@pytest.fixture(scope="module")
def slider():
    sc = kf.Scene(mechanisms.build("slider_crank", elements=4), steps=60, effects=("inertia", "coupling"),
                  damping=kf.Rayleigh(0.0, 3e-5))
    return kf.solve(sc)


@pytest.fixture(scope="module")
def sixbar():
    sc = kf.Scene(mechanisms.build("six_bar", elements=2), steps=24, damping=kf.ModalDamping(0.02))
    return kf.solve(sc)


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_peaks_csv_equals_result_peaks(slider, tmp_path):
    head, rows = read_csv(export.write_peaks_csv(slider, tmp_path / "peaks.csv"))
    assert head[:4] == ["link", "peak_deflection_m", "deflection_angle_rad", "peak_stress_Pa"]
    peaks = slider.peaks()
    assert [r[0] for r in rows] == [p.link for p in peaks]
    for r, p in zip(rows, peaks):
        assert [float(x) for x in r[1:6]] == [p.deflection, p.deflection_angle, p.stress, p.stress_angle,
                                              p.stress_station]
        e = slider.error.link(p.link)   # the time-discretisation estimate travels with the peaks
        assert [float(x) for x in r[6:8]] == [e.deflection, e.stress]
        assert r[8:10] == ["", ""]   # no mesh estimate passed


def test_response_and_frequency_csv_and_npz_round_trip(slider, tmp_path):
    head, rows = read_csv(export.write_response_csv(slider, tmp_path / "r.csv"))
    assert head[:2] == ["t_s", "crank_angle_rad"]
    assert head[2:] == [f"{d}_{'rad' if d.split('.')[-1].split('@')[0] in ('theta', 'phi') else 'm'}"
                        for d in slider.dof_labels]
    data = np.array(rows, dtype=float)
    np.testing.assert_array_equal(data[:, 0], slider.t)
    np.testing.assert_array_equal(data[:, 2:], slider.U)
    f = slider.frequencies(3)
    head, rows = read_csv(export.write_frequencies_csv(f, tmp_path / "f.csv"))
    assert tuple(head) == export.FREQUENCY_COLUMNS  # tidy: one row per time node and mode
    data = np.array([r[:5] for r in rows], dtype=float)
    np.testing.assert_array_equal(data[:, 0], np.repeat(f.crank_angle, 3))
    np.testing.assert_array_equal(data[:, 1], np.tile([1, 2, 3], f.crank_angle.size))
    np.testing.assert_array_equal(data[:, 2].reshape(-1, 3), f.modal)
    np.testing.assert_array_equal(data[:, 3].reshape(-1, 3), f.state_space)
    assert {r[5] for r in rows} == {"True"}
    z = np.load(export.write_npz(slider, tmp_path / "r.npz", f))
    np.testing.assert_array_equal(z["U"], slider.U)
    np.testing.assert_array_equal(z["floquet_multipliers"], slider.floquet_multipliers)
    assert tuple(z["dof_labels"]) == slider.dof_labels and bool(z["converged"]) is slider.converged
    np.testing.assert_array_equal(z["state_space"], f.state_space)
    np.testing.assert_array_equal(z["frequency_crank_angle"], f.crank_angle)  # the frequencies' own grid
    assert str(z["crank_angle_convention"]) == "of the crank 'crank', absolute (its O -> A line from +x, " \
        "counter-clockwise)"  # a driven link's angle, named with the data


def test_vtk_series_reads_back_equal_to_the_result(slider, tmp_path):
    s = export.write_vtk_series(slider, tmp_path, scale=100.0)
    assert s.pvd == tmp_path / "response" / "response.pvd" and len(s.files) == slider.n
    reader = pv.get_reader(str(s.pvd))
    np.testing.assert_array_equal(reader.time_values, slider.t)
    rod, crank = (next(p for p in s.parts if p.name == n) for n in ("rod", "crank"))
    assert rod.kind == "flexible link" and crank.kind == "rigid link"
    for k in (0, 17, 59):
        reader.set_active_time_point(k)
        g = reader.read()[0]
        assert g.field_data["time"][0] == slider.t[k] and g.field_data["scale"][0] == 100.0
        d = g.point_data["displacement"]
        assert d.shape == (g.n_points, 3) and np.all(d[:, 2] == 0) and np.all(g.points[:, 2] == 0)
        np.testing.assert_allclose(d[rod.points, :2], slider.link_displacement("rod")[k], rtol=0, atol=1e-15)
        geo = slider.link_geometry("rod")[k]
        np.testing.assert_allclose(g.point_data["position"][rod.points, :2],
                                   geo + slider.link_displacement("rod")[k], rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(g.points[rod.points, :2], geo + 100.0 * slider.link_displacement("rod")[k],
                                   rtol=1e-6, atol=1e-9)  # VTK stores points as written (float64)
        np.testing.assert_allclose(d[crank.points, :2],
                                   np.stack([slider.joint_displacement("O")[k], slider.joint_displacement("A")[k]]),
                                   atol=1e-15)
        ax = g.cell_data["axial_force"]
        np.testing.assert_allclose(ax[rod.cells], slider.axial_force("rod")[k], rtol=1e-14)
        # no NaN in the file: the rigid crank has no section forces, 0 with its flag 0
        assert (ax[crank.cells] == 0).all() and (g.cell_data["stress"][crank.cells] == 0).all()
        flag = g.cell_data["section_forces_computed"]
        assert (flag[crank.cells] == 0).all() and (flag[rod.cells] == 1).all()
        assert (g.point_data["stress_computed"][rod.points] == 1).all()
        np.testing.assert_allclose(g.point_data["nodal_stress"][rod.points], slider.stress("rod")[k], rtol=1e-14)
        np.testing.assert_array_equal(g.cell_data["part_id"][rod.cells], rod.part_id)
        assert set(np.asarray(g.celltypes)) == {pv.CellType.LINE}
    assert "0 = crank (rigid link)" in s.pvd.read_text()


def test_every_and_auto_scale(slider, tmp_path):
    s = export.write_vtk_series(slider, tmp_path, every=7)
    np.testing.assert_array_equal(s.frames, np.arange(0, slider.n, 7))
    np.testing.assert_array_equal(pv.get_reader(str(s.pvd)).time_values, slider.t[::7])
    mesh = export.mechanism_mesh(slider)
    dmax = np.linalg.norm(mesh.displacement, axis=-1).max()
    r = mesh.rigid.reshape(-1, 2)
    size = np.linalg.norm(r.max(0) - r.min(0))
    assert 0.02 * size <= s.scale * dmax <= 0.05 * size * (1 + 1e-12)
    with pytest.raises(kf.InputError, match="every"):
        export.write_vtk_series(slider, tmp_path, every=0)
    with pytest.raises(kf.InputError, match="scale"):
        export.write_vtk_series(slider, tmp_path, scale=float("nan"))


def test_bodies_are_polygons_and_mode_shapes_have_their_own_files(sixbar, tmp_path):
    s = export.write_vtk_series(sixbar, tmp_path)
    g = pv.read(s.files[0])
    body = next(p for p in s.parts if p.kind == "body")
    assert body.name == "bellcrank"
    assert pv.CellType.POLYGON in set(np.asarray(g.celltypes))
    np.testing.assert_allclose(g.point_data["displacement"][body.points, :2],
                               np.stack([sixbar.joint_displacement(j)[0] for j in ("O4", "B", "C")])[
                                   export._polygon_order(np.array([sixbar.model.mech.joints[j].at
                                                                   for j in ("O4", "B", "C")]))], atol=1e-15)
    m = export.write_mode_shapes(sixbar, tmp_path, n_modes=3)
    assert m.pvd.name == "modes.pvd" and len(m.files) == 3
    np.testing.assert_array_equal(pv.get_reader(str(m.pvd)).time_values, [1.0, 2.0, 3.0])
    f, phi = sixbar.mode_shapes(0, 3)
    for j, path in enumerate(m.files):
        g = pv.read(path)
        assert g.field_data["frequency"][0] == pytest.approx(f[j], rel=1e-12)
        d = g.point_data["displacement"]
        assert np.linalg.norm(d, axis=1).max() == pytest.approx(1.0, rel=1e-12)
        crank = next(p for p in m.parts if p.name == "crank")
        u = sixbar.link_displacement("crank", U=np.broadcast_to(phi[:, j], sixbar.U.shape))[0]
        scale = np.linalg.norm(u, axis=1).max() / np.linalg.norm(d[crank.points, :2], axis=1).max()
        np.testing.assert_allclose(d[crank.points, :2] * scale, u, rtol=1e-10, atol=1e-14)


def listing(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def test_interrupted_series_leaves_no_half_written_output(slider, tmp_path, monkeypatch):
    real = export._write_vtu
    calls = []

    def failing(path, mesh, field=None):
        calls.append(path)
        if len(calls) == 5:
            raise OSError(28, "No space left on device")
        real(path, mesh, field)

    monkeypatch.setattr(export, "_write_vtu", failing)
    with pytest.raises(OSError, match="No space"):
        export.write_vtk_series(slider, tmp_path)
    assert listing(tmp_path) == []
    # with a previous series in place: it survives unchanged
    monkeypatch.setattr(export, "_write_vtu", real)
    s = export.write_vtk_series(slider, tmp_path, every=10)
    before = {p: (tmp_path / p).read_bytes() for p in listing(tmp_path) if (tmp_path / p).is_file()}
    calls.clear()
    monkeypatch.setattr(export, "_write_vtu", failing)
    with pytest.raises(OSError):
        export.write_vtk_series(slider, tmp_path, every=1)
    after = {p: (tmp_path / p).read_bytes() for p in listing(tmp_path) if (tmp_path / p).is_file()}
    assert after == before and len(s.files) == -(-slider.n // 10)
    # a successful rewrite replaces it completely (no stale frames)
    monkeypatch.setattr(export, "_write_vtu", real)
    export.write_vtk_series(slider, tmp_path, every=20)
    assert len(list((tmp_path / "response").glob("*.vtu"))) == -(-slider.n // 20)
    assert not [p for p in listing(tmp_path) if p.startswith(".")]


def test_atomic_path_keeps_the_old_file_on_failure(tmp_path):
    target = tmp_path / "a.csv"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with export.atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert target.read_text() == "old" and listing(tmp_path) == ["a.csv"]
    with export.atomic_path(target) as tmp:
        assert tmp.suffix == ".csv" and tmp.parent == tmp_path
        tmp.write_text("new")
    assert target.read_text() == "new" and listing(tmp_path) == ["a.csv"]


def png_is_not_blank(path):
    import matplotlib.image as mpimg
    img = mpimg.imread(str(path))[..., :3]
    assert img.shape[0] >= 200 and img.shape[1] >= 200
    white = np.all(img > 0.97, axis=-1)
    inked = 1.0 - white.mean()
    colours = len(np.unique((img.reshape(-1, 3) * 255).astype(np.uint8), axis=0))
    assert 0.002 < inked < 0.9, f"fraction of non-background pixels {inked:.4f}"
    assert colours >= 16, f"only {colours} distinct colours"
    assert img.std() > 0.02
    return inked


def test_offscreen_render_is_not_blank(slider, tmp_path):
    from kedfem.io import render
    s = export.write_vtk_series(slider, tmp_path, every=5)
    png = render.render_series(s, tmp_path / "deformed.png")
    assert png.is_file() and png_is_not_blank(png)
    assert render.headless_environment() == (not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")))
    with pytest.raises(kf.InputError):
        render.render_series(s, tmp_path / "x.png", frame=99)


def test_modules_import_without_heavy_libraries():
    code = ("import sys; import kedfem.cli, kedfem.io.scenefile, kedfem.io.export, kedfem.io.plots, kedfem.io.render, "
            "kedfem.io.sweep; print(','.join(m for m in ('matplotlib', 'pyvista', 'meshio', 'vtk', 'dask', "
            "'distributed', 'tqdm') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
