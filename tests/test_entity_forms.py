"""Entity forms (kedfem.fe.forms.EntityForm): every entity of a model has one, of consistent shapes.

The group maps add an entity's map rates and offsets where :meth:`FEModel.entity_dynamic` says
they are (kedfem.fe.maps.DynamicSlot): a form must carry rates exactly where it is said to
move and an offset only where it is said to have one, or they would be left out silently. The mechanisms between them have every kind of entity:
fixed, free, slider, body, corotated, slot, contact and Craig-Bampton points; free, fixed (with
an offset), slot and Craig-Bampton rotations.
"""

from __future__ import annotations

import math

import pytest

import kedfem as kf
from kedfem.fe.forms import EntityForm
from kedfem.fe.maps import DynamicSlot, PassiveEnd

STEEL = kf.Material(E=2.0e11, rho=7850.0)
NT = 12


def _block_and_reduced_rod():
    """A block driven along a cantilever by a slider-crank whose rod is reduced (Craig-Bampton)."""
    m = kf.Mechanism("block-on-cantilever")
    m.ground("O", at=(0.0, 0.0), clamped=True)
    m.joint("T", at=(0.5, 0.0))
    m.ground("O2", at=(-0.15, 0.0))
    m.joint("P", at=(-0.05, 0.0))
    m.slider("B", at=(0.35, 0.0), on="beam")
    m.link("beam", "O", "T", material=STEEL, section=kf.Section.rectangle(0.02, 0.01), elements=6)
    m.link("crank", "O2", "P", material=STEEL, section=kf.Section.rectangle(0.03, 0.03), elements=1)
    m.link("rod", "P", "B", material=STEEL, section=kf.Section.rectangle(0.03, 0.03), elements=4)
    m.drive("crank", speed=2 * math.pi)
    return m, kf.CraigBampton(modes=2, links=("rod",))


def _scotch_yoke():
    """A crank's pin block in the slot of a rigid yoke on a crosshead guide."""
    m = kf.Mechanism("scotch-yoke")
    m.ground("O2", at=(0.0, 0.0))
    m.slider("A", at=(0.05, 0.0), on="yoke", axis=(0.0, 1.0))
    m.slider("Y", at=(0.25, 0.0), axis=(1.0, 0.0), rotation="locked")
    m.link("crank", "O2", "A", material=STEEL, section=kf.Section.rectangle(0.03, 0.03), elements=2)
    m.body("yoke", ("Y",), mass=1.0, J=0.01, cm=(0.25, 0.0))
    m.drive("crank", speed=20 * math.pi)
    return m, None


def _piston_on_a_lever():
    """A coupler's end block slides along a flexible lever, its rotation locked to the lever's slope."""
    m = kf.Mechanism("piston-on-lever")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=(0.3, 0.0))
    m.joint("P", at=(0.0, 0.06))
    m.joint("C", at=(0.1, 0.35))
    m.slider("X", at=(0.2, 0.175), on="lever", rotation="locked")
    m.link("lever", "O4", "C", material=STEEL, section=kf.Section.rectangle(0.012, 0.02), elements=4)
    m.link("crank", "O2", "P", rigid=True, mass=0.3)
    m.link("coupler", "P", "X", material=STEEL, section=kf.Section.rectangle(0.008, 0.01), elements=2)
    m.drive("crank", speed=2 * math.pi)
    return m, None


CASES = [(_block_and_reduced_rod, True), (_scotch_yoke, True), (_scotch_yoke, False), (_piston_on_a_lever, True)]


@pytest.mark.parametrize("build, corotate", CASES)
def test_every_entity_has_a_consistent_form(build, corotate):
    mech, reduction = build()
    fe = kf.FEModel(mech, reduction=reduction, corotate=corotate)
    forms = fe.entity_forms(kf.kinematics(mech, NT))
    assert len(forms["P"]) == len(fe.points) and len(forms["R"]) == len(fe.rots)
    for kind, width in (("P", 2), ("R", 1)):
        for eid, f in enumerate(forms[kind]):
            assert isinstance(f, EntityForm)
            cols, C, C1, C2, p, p1, p2 = f  # still unpacks as the 7-tuple
            assert cols == fe.entity_cols(kind, eid)
            assert C.ndim == 3 and C.shape[0] in (1, NT) and C.shape[1:] == (width, len(cols))
            moving, offset = fe.entity_dynamic(kind, eid)
            assert (C1 is not None) == (C2 is not None) == moving, (kind, eid)
            if moving:
                assert C1.shape == C.shape and C2.shape == C.shape
            assert (p is not None) == (p1 is not None) == (p2 is not None)
            if p is not None:  # (the flag may be set without: a block that never reaches an offset node)
                assert offset, (kind, eid)
                assert p.shape == p1.shape == p2.shape == (NT, width)


def test_the_cases_hold_every_kind_of_entity():
    kinds = set()
    for build, corotate in CASES:
        mech, reduction = build()
        fe = kf.FEModel(mech, reduction=reduction, corotate=corotate)
        kinds |= {("P", pd.kind) for pd in fe.points} | {("R", rd.kind) for rd in fe.rots}
        kinds |= {("R", "offset") for rd in fe.rots if rd.offset}
    assert {("P", k) for k in ("fixed", "free", "slider", "body", "corot", "slot", "contact", "cb")} <= kinds
    assert {("R", k) for k in ("free", "fixed", "slot", "cb", "offset")} <= kinds


def test_group_maps_read_the_forms_through_named_slots():
    mech, reduction = _block_and_reduced_rod()
    fe = kf.FEModel(mech, reduction=reduction)
    mo = kf.kinematics(mech, NT)
    forms = fe.entity_forms(mo)
    seen = 0
    for g in fe.groups:
        for key in fe.buckets(g):
            _cols, E0, dynamic, passive = fe._static_layout(key)
            for dyn in dynamic:
                assert isinstance(dyn, DynamicSlot)
                assert dyn.width == (2 if dyn.kind == "P" else 1)
                assert dyn.positions.size == len(forms[dyn.kind][dyn.eid].cols)
                assert 0 <= dyn.element < E0.shape[0] and dyn.row + dyn.width <= E0.shape[1]
                seen += 1
            assert all(isinstance(pe, PassiveEnd) for pe in passive)
            gm = fe.group_map(key, mo, forms)
            assert gm.E.shape[1:] == E0.shape
    assert seen
