"""Fuzz the example scene files: mutated, they load and solve, or fail with a named KedError.

Each example in ``examples/scenes`` is read, one to three of its keys (or
new ones) are replaced by random values, removed or added, the result is
written back as TOML and driven through the loader and a short solve (24 time
elements, at most 200 DOFs). No exception other than a :class:`KedError`
may escape, a scene-file error names its key, and every error is one line.
Bounded to well under a minute (hypothesis, 300 examples, about a fifth of them solved).
"""

import dataclasses
import tomllib
import warnings
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st
from test_scenefile import keys, mutate, to_toml, values  # tests/ is on sys.path under pytest

import kedfem as kf
from kedfem.io import scenefile as sf

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples" / "scenes").glob("*.toml"))
TABLES = ("", "mechanism", "damping", "solver", "output", "sweep")
#: keys the examples use, with plausible and edge values: most mutations should reach the solve
PLAUSIBLE = st.one_of(
    st.tuples(st.just(""), st.sampled_from(["speed_rpm", "rtol", "steps", "effects", "method", "hold"]),
              st.sampled_from([1.0, 60.0, 200.0, 3000.0, 1e-3, 1e-6, 0.5, 24, 48, 7, "radau3", "gauss2",
                               "magnus2", "zoh", "fourier", ["inertia"], ["inertia", "coupling", "gravity"],
                               "all", ["inertia", "geometric_nonlinearity"], 0, -1, 1e300])),
    st.tuples(st.just("mechanism"), st.sampled_from(["elements", "speed", "crank_angle", "E", "rho"]),
              st.sampled_from([1, 2, 3, 4, 0, -2, 0.5, 1e-3, 1e12, 2.0, 7e10])),
    st.tuples(st.just("damping"), st.sampled_from(["model", "zeta", "alpha", "beta"]),
              st.sampled_from(["modal", "rayleigh", "none", 0.0, 0.02, 0.5, 2.0, 1e-5, -0.1])),
    st.tuples(st.just("solver"), st.sampled_from(["eps", "max_iter", "nonlinear_method"]),
              st.sampled_from([1e-3, 1e-9, 3, 1, "anderson", "relaxation"])),
)


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.sampled_from(EXAMPLES), st.lists(st.one_of(PLAUSIBLE, PLAUSIBLE, st.tuples(
    st.sampled_from(TABLES), keys, st.one_of(st.none(), values))), min_size=1, max_size=3))
def test_mutated_example_scenes_load_and_solve_or_name_the_problem(tmp_path, path, muts):
    d = mutate(muts, tomllib.loads(path.read_text()))
    try:
        text = to_toml(d)
    except TypeError:
        assume(False)
    p = tmp_path / path.name
    p.write_text(text, encoding="utf-8")
    try:
        scene, _outputs = sf.load_scene(p)
    except sf.SceneFileError as e:
        event("scene-file error")
        assert "\n" not in str(e) and (e.key or e.line or "TOML" in str(e)), str(e)
        if e.key:
            assert sf._keyfmt(e.key) in str(e)
        return
    from kedfem.fe.model import FEModel
    try:
        n_dof = FEModel(scene.mech, reduction=scene.reduction).n_dof
    except kf.KedError as e:
        assert str(e) and "\n" not in str(e)
        return
    assume(n_dof <= 200)
    short = dataclasses.replace(scene, steps=24, estimate=False)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = kf.solve(short)
    except kf.KedError as e:
        event(f"solve: {type(e).__name__}")
        assert str(e).strip() and "\n" not in str(e).strip(), str(e)
        return
    event("solved")
    assert np.all(np.isfinite(res.U)) or not res.converged
