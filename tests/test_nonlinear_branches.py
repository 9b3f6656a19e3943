"""Non-linear responses of the four-bar preset (issue 24): Newton converges quadratically on a
branch; pushed from 100 to 600 rpm, every kf.solve ends in a converged response with a verdict
from its own orbit, or in a named NonlinearSolveError, never in the numbers of a diverged iterate."""

import math
import warnings

import numpy as np
import pytest

import kedfem as kf
from kedfem.catalogue import info

RPM = 2 * math.pi / 60


def scene(rpm, **kw):
    return info("four_bar").scene({}, speed=rpm * RPM, **kw)


def test_newton_converges_quadratically_from_a_neighbour():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = kf.solve(scene(300, steps=48, estimate=False))
        res = kf.solve(scene(303, steps=48, estimate=False, eps=1e-9), start=base)
    h = np.array(res.history)
    assert res.converged and len(h) <= 8, h
    # the last two corrections: each below a constant times the square of the one before (down to
    # round-off, ~1e-11): the quadratic rate of Newton's method with the consistent tangent
    assert h[-2] <= 50.0 * h[-3] ** 2 and h[-1] <= 50.0 * h[-2] ** 2 + 1e-10, h


def test_a_speed_sweep_ends_in_answers_or_named_failures():
    seen = []
    for rpm in (100, 300, 450, 600):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                res = kf.solve(scene(rpm, steps=24, estimate=False))
            except kf.NonlinearSolveError as e:
                assert f"{rpm:g} rpm" in str(e) and "Next:" in str(e)
                seen.append("failure")
                continue
        assert res.converged and res.stability.verdict in ("stable", "unstable", "marginal")
        assert res.stable == (res.stability.verdict == "stable")
        for p in res.peaks():  # an answer: finite and not the runaway of a diverged iterate
            assert np.isfinite([p.deflection, p.stress]).all() and p.deflection < 0.05
        seen.append(res.stability.verdict)
    assert seen[:2] == ["stable", "stable"], seen


def test_a_fixed_point_iteration_that_fails_is_a_named_error():
    """The paper's iteration, asked explicitly and limited to 3 solves at 350 rpm: no result."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(kf.NonlinearSolveError, match="did not converge within max_iter = 3") as e:
            kf.solve(scene(350, steps=24, nonlinear_method="fixed-point", max_iter=3))
    assert "nonlinear_method='newton'" in str(e.value)


def test_the_command_line_exits_non_zero_and_writes_no_peaks(tmp_path):
    """The same failure from `kedfem run`: a one-line named error, exit status non-zero, and no
    output folder with peaks in it."""
    import subprocess
    import sys
    (tmp_path / "s.toml").write_text('mechanism = "four_bar"\nspeed_rpm = 350\nsteps = 24\n'
                                     '[solver]\nnonlinear_method = "fixed-point"\nmax_iter = 3\n')
    r = subprocess.run([sys.executable, "-m", "kedfem.cli", "run", "s.toml", "--out", "out"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode != 0
    assert "no periodic response found at 350 rpm" in r.stderr and "Traceback" not in r.stderr
    assert not list(tmp_path.rglob("peaks.csv"))


def test_newton_stops_on_the_rate_of_a_coarser_level():
    """A finer level's Newton stops on a change whose successor the coarser level's rate predicts
    below eps / 10, one solve early, and the response it returns is that close to the solution."""
    from kedfem.analysis.pipeline import _Run
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = _Run(scene(200))
        ti, coarse = run.problem(48)
        c = coarse.solve(None, eps=1e-4, max_iter=30)
        assert c.converged and c.rate is not None and c.predicted is None
        ti, fine = run.problem(96)
        x0 = c.discrete.at(ti)
        quick = fine.solve(x0, eps=1e-4, max_iter=30, rate=c.rate)
        plain = fine.solve(x0, eps=1e-4, max_iter=30)
        ref = fine.solve(x0, eps=1e-9, max_iter=30)
    assert quick.converged and plain.converged and ref.converged
    # without a rate only a change below eps stops it; with one, a solve earlier
    assert quick.predicted is not None and plain.predicted is None and plain.history[-1] <= 1e-4
    assert quick.iterations == plain.iterations - 1 and quick.history == plain.history[:-1]
    assert quick.history[-1] > 1e-4 and quick.predicted <= 1e-5
    U, Uref = (s.discrete.at(ti)[0] for s in (quick, ref))
    err = float(np.linalg.norm(U - Uref) / np.linalg.norm(Uref))
    # the distance from the solution: below eps, and below the prediction (an upper estimate)
    assert err <= 1e-4 and err <= quick.predicted, (err, quick.predicted)


def test_a_continuation_starts_from_the_given_start():
    """Pushed past where Newton converges from the linear response, a solve given the result at a
    lower speed continues from that speed (fewer steps), to the same response as on its own."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = kf.solve(scene(340, steps=24, estimate=False))
        given = kf.solve(scene(400, steps=24, estimate=False), start=base)
        alone = kf.solve(scene(400, steps=24, estimate=False))
    assert "from 340 rpm" in given.path and "the given start" in given.path, given.path
    assert "from 340 rpm" not in alone.path and "the linear response" in alone.path, alone.path
    assert given.iterations < alone.iterations  # measured 175 and 372 linear solves
    a = np.array([[p.deflection, p.stress] for p in given.peaks()])
    b = np.array([[p.deflection, p.stress] for p in alone.peaks()])
    assert np.max(np.abs(a / b - 1)) < 1e-6
