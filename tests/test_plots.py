"""Plots: PNG files with labelled SI axes, drawn from the right data, without pyplot."""

import dataclasses

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.io import plots

matplotlib = pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def res():
    sc = kf.Scene(mechanisms.build("slider_crank", elements=4), steps=48, damping=kf.ModalDamping(0.02))
    return kf.solve(sc)


@pytest.fixture
def figures(monkeypatch):
    """Capture the figures the plot functions save."""
    captured = []
    real = plots._save

    def save(fig, path):
        captured.append(fig)
        return real(fig, path)

    monkeypatch.setattr(plots, "_save", save)
    return captured


def is_png(path):
    import matplotlib.image as mpimg
    img = mpimg.imread(str(path))
    assert img.ndim == 3 and img.shape[0] > 100 and img[..., :3].std() > 0.01
    return True


def labels(fig):
    return [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes if ax.get_visible()]


def test_result_plots(res, tmp_path, figures):
    backend = matplotlib.get_backend()
    paths = plots.all_plots(res, tmp_path, res.frequencies(2))
    assert [p.name for p in paths] == ["displacement.png", "link_response.png", "frequencies.png", "floquet.png"]
    assert all(is_png(p) for p in paths)
    disp, link, freq, flo = figures
    crank = "crank angle [deg] ('crank', absolute)"  # the convention named: a driven link's own angle
    assert labels(disp)[0] == (crank, "elastic displacement [m]")
    assert labels(link) == [(crank, "mid-span deflection [mm]"),
                            (crank, "max. normal stress along link [MPa]")]
    assert labels(freq) == [(crank, "natural frequency [Hz]")]
    assert labels(flo) == [("Re(mu) [-]", "Im(mu) [-]")]
    # the drawn data are the result's
    line = link.axes[0].lines[0]
    w = res.deflection("rod", 0.5, relative_to="chord")
    np.testing.assert_array_equal(line.get_ydata(), 1e3 * np.append(w, w[0]))      # closed over the cycle
    s = res.stress("rod").max(axis=1)
    np.testing.assert_array_equal(link.axes[1].lines[0].get_ydata(), 1e-6 * np.append(s, s[0]))
    x = line.get_xdata()
    assert x[0] == 0 and x[-1] == 360 and np.all(np.diff(x) > 0)
    np.testing.assert_allclose(x[:-1], np.degrees(res.crank_angle - res.crank_angle[0]) % 360, atol=1e-9)
    mu = flo.axes[0].lines[1]
    np.testing.assert_array_equal(mu.get_xdata(), res.floquet_multipliers.real)
    assert matplotlib.get_backend() == backend  # no global backend switch


def test_displacement_dofs(res, tmp_path, figures):
    plots.displacement(res, tmp_path / "d.png", ["rod.n1.v", "rod.n2.theta"])
    fig = figures[0]
    assert [ax.get_ylabel() for ax in fig.axes] == ["elastic displacement [m]", "elastic rotation [rad]"]
    np.testing.assert_array_equal(fig.axes[0].lines[0].get_ydata()[:-1], res.dof("rod.n1.v"))
    with pytest.raises(kf.InputError, match="rod.n1.uz"):
        plots.displacement(res, tmp_path / "d.png", ["rod.n1.uz"])
    auto = plots.auto_dofs(res, 2)
    from kedfem.io.export import dof_unit
    amp = {d: np.ptp(res.dof(d)) for d in res.dof_labels if dof_unit(d) == "m"}
    assert set(auto) == set(sorted(amp, key=amp.get)[-2:])


@dataclasses.dataclass
class Run:
    knob: str
    steps: int
    wall_time: float
    error: float


def test_accuracy_vs_cost_accepts_tidy_tables(tmp_path, figures):
    rows = [Run(h, s, 1e-3 * s * (i + 1), float(s) ** -(i + 1)) for i, h in enumerate(["zoh", "foh"])
            for s in (120, 30, 60)]
    rows.append(Run("foh", 240, 0.5, 0.0))        # cannot be drawn on log axes: skipped
    for table in (rows, [dataclasses.asdict(r) for r in rows],
                  {k: [getattr(r, k) for r in rows] for k in ("knob", "steps", "wall_time", "error")}):
        figures.clear()
        p = plots.accuracy_vs_cost(table, tmp_path / "acc.png", label="steps", title="holds")
        assert is_png(p)
        ax = figures[0].axes[0]
        assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
        assert ax.get_xlabel() == "wall time [s]" and ax.get_ylabel() == "relative error [-]"
        curves = {ln.get_label(): ln for ln in ax.lines}
        assert set(curves) == {"zoh", "foh"}
        np.testing.assert_array_equal(curves["foh"].get_xdata(), [0.06, 0.12, 0.24])   # sorted by cost
        np.testing.assert_array_equal(curves["zoh"].get_ydata(), [1 / 30, 1 / 60, 1 / 120])
    with pytest.raises(kf.InputError, match="'err'"):
        plots.accuracy_vs_cost(rows, tmp_path / "x.png", error="err")


def test_sweep_peaks(tmp_path, figures):
    t = dict(speed_rpm=[300, 100, 200, 100, 200, 300], link=["a", "a", "a", "b", "b", "b"],
             peak_stress_Pa=[3.0, 1.0, 2.0, 2.0, 3.0, float("nan")])
    assert is_png(plots.sweep_peaks(t, tmp_path / "s.png"))
    ax = figures[0].axes[0]
    assert ax.get_xlabel() == "speed [rev/min]" and ax.get_ylabel() == "peak dynamic stress [Pa]"
    a, b = ax.lines
    np.testing.assert_array_equal(a.get_xdata(), [100, 200, 300])
    np.testing.assert_array_equal(a.get_ydata(), [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(b.get_xdata(), [100, 200])   # the NaN point is left out
