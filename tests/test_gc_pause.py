"""The cyclic garbage collector paused during jaxskid's long steps (jaxskid._gc): off inside, as it was after,
also when an error leaves the step; a collector the caller turned off stays off."""

from __future__ import annotations

import gc

import pytest

import jaxskid
import jaxskid._api
from jaxskid._gc import gc_paused, paused_gc


def test_paused_and_restored():
    assert gc.isenabled()
    with paused_gc():
        assert not gc.isenabled()
        with paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()  # the inner pause leaves the outer one's state
    assert gc.isenabled()
    with pytest.raises(ValueError):
        with paused_gc():
            raise ValueError
    assert gc.isenabled()
    gc.disable()
    try:
        with paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()  # the caller's choice stays
    finally:
        gc.enable()


def test_the_long_steps_pause_it(monkeypatch):
    """load (here its inertia checks), derive and lower run paused and keep their signatures and docstrings;
    a load that fails leaves the collector on."""
    from helpers import ROBOTS_DIR


    seen = []
    check = jaxskid._api.check_inertias
    monkeypatch.setattr(jaxskid._api, "check_inertias", lambda *a: (seen.append(gc.isenabled()), check(*a)))
    jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    assert seen == [False] and gc.isenabled()
    with pytest.raises(jaxskid.ModelError):
        jaxskid.load("no-such-robot.urdf")
    assert gc.isenabled()
    for fn in (jaxskid.load, jaxskid.derive, jaxskid.lower):
        assert fn.__wrapped__.__doc__ == fn.__doc__ and fn.__name__ == fn.__wrapped__.__name__
    inside = []
    gc_paused(lambda: inside.append(gc.isenabled()))()
    assert inside == [False] and gc.isenabled()
