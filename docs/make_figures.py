"""Regenerate the README's figures and the numbers quoted next to them.

Run: ``python docs/make_figures.py`` (about a minute on 2 cores). Writes
``docs/img/*.png`` and prints the slider-crank peaks and the Table 3
comparison that the README quotes.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np

import kedfem as kf
import mechanisms
from kedfem.io import export, plots, render

IMG = Path(__file__).resolve().parent / "img"


def slider_crank_peaks():
    """Mid-span deflection of the slider-crank rod, with and without axial stiffening."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(8, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    rows = []
    for eff, style in ((("inertia", "coupling"), "-"), (("inertia", "coupling", "axial_stiffening"), "--")):
        sc = kf.Scene(mechanisms.build("slider_crank", elements=8), rtol=1e-6, effects=eff,
                      damping=kf.Rayleigh(alpha=0.0, beta=3e-5))
        res = kf.solve(sc)
        w = res.deflection("rod", 0.5, relative_to="chord")
        deg = np.degrees(res.crank_angle)
        pk = res.peaks()[0]   # refined between the output instants
        rows.append((" + ".join(eff), pk.deflection * 1e3, math.degrees(pk.deflection_angle) % 360,
                     res.error.link("rod").deflection, kf.mesh_error(res).link("rod").deflection))
        ax.plot(np.append(deg, 360), np.append(w, w[0]) * 1e3, style, label=" + ".join(eff))
    ax.set_xlabel("crank angle [deg]")
    ax.set_ylabel("mid-span deflection (chord) [mm]")
    ax.set_title("slider-crank, 150 rad/s, zeta ~ 0.02: periodic steady state")
    ax.set_xlim(0, 360)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(IMG / "slider_crank_deflection.png", dpi=110)
    for name, wmax, ang, et, em in rows:
        print(f"slider-crank, {name}: peak |mid-span deflection| {wmax:.4f} mm at crank angle {ang:.1f} deg "
              f"(estimated errors: time {et:.0e}, mesh {em:.0e})")


def mould_pictures():
    res = kf.solve(kf.default_scene())
    plots.link_response(res, IMG / "mould_link_response.png")
    with tempfile.TemporaryDirectory() as tmp:
        series = export.write_vtk_series(res, tmp, scale=200.0)
        frames = sorted(Path(tmp).glob("response/*.vtu"))
        render.render_frame(frames[len(frames) // 4], IMG / "mould_render.png",
                            title="mould oscillator, deformation x 200, colour: stress [MPa]")
        del series
    print(kf.table3().table())


def whitworth_pictures():
    """The Whitworth preset: the slotted lever's deflection over the cycle, a render and the cycle GIF."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from kedfem.fe.slots import block_abscissa
    res = kf.solve(kf.Scene(mechanisms.build("whitworth"), effects=("inertia", "coupling", "axial_stiffening"),
                            damping=kf.ModalDamping(0.02)))
    lever = res.model.mech.links["lever"]
    xi = np.linspace(0.0, 1.0, 61)
    shape = np.stack([res.deflection("lever", x) for x in xi], axis=1) * 1e3  # (n, 61) [mm]
    block = block_abscissa(res.model, "A", res.motion)
    fig = Figure(figsize=(8, 4.4))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    deg = np.degrees(res.crank_angle) % 360
    picks = [int(np.argmin(np.abs((deg - a + 180) % 360 - 180))) for a in range(0, 360, 30)]
    import matplotlib
    cmap = matplotlib.colormaps["twilight"]
    for k in picks:
        col = cmap(deg[k] / 360)
        ax.plot(xi * lever.length * 1e3, shape[k], color=col, label=f"{deg[k]:.0f} deg")
        ax.plot(block[k] * 1e3, np.interp(block[k] / lever.length, xi, shape[k]), "o", color=col)
    ax.set_xlabel("abscissa along the lever from O4 [mm] (dots: the sliding block)")
    ax.set_ylabel("deflection [mm]")
    ax.set_title("Whitworth quick-return, 120 rpm: the slotted lever under the moving block")
    ax.grid(alpha=0.3)
    ax.legend(ncol=2, fontsize=7, title="crank angle")
    fig.tight_layout()
    fig.savefig(IMG / "whitworth_lever.png", dpi=110)
    with tempfile.TemporaryDirectory() as tmp:
        series = export.write_vtk_series(res, tmp, scale=100.0)
        frames = sorted(Path(tmp).glob("response/*.vtu"))
        peak = res.peaks()[1]
        k = int(np.argmin(np.abs(np.mod(res.crank_angle, 2 * math.pi) - peak.stress_angle)))
        render.render_frame(frames[k * len(frames) // res.n], IMG / "whitworth_render.png",
                            title="Whitworth quick-return, deformation x 100, colour: stress [MPa]")
        render.render_animation(series, IMG / "whitworth_cycle.gif", max_frames=36, fps=10)
    print(res.summary())


if __name__ == "__main__":
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    IMG.mkdir(parents=True, exist_ok=True)
    slider_crank_peaks()
    mould_pictures()
    whitworth_pictures()
