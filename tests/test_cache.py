"""The on-disk cache of generated modules: reuse, corruption, concurrent writers."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import jaxskid
from jaxskid.lowering._cache import seal

ROBOT = Path(__file__).parents[1] / "robots" / "double_pendulum.yaml"


def test_second_lower_reads_the_cache(tmp_path):
    robot = jaxskid.load(ROBOT)
    first = jaxskid.lower(robot, ["mass_matrix"], cache_dir=tmp_path)
    assert first.path is not None and first.path.exists()
    second = jaxskid.lower(robot, ["mass_matrix"], cache_dir=tmp_path)
    assert second.source == first.source and second.path == first.path
    other = jaxskid.lower(robot, ["gravity_torques"], cache_dir=tmp_path)
    assert other.path != first.path, "a different request is a different entry"
    assert len(list(tmp_path.glob("*.py"))) == 2


def test_truncated_or_corrupted_entry_is_regenerated(tmp_path):
    robot = jaxskid.load(ROBOT)
    dyn = jaxskid.lower(robot, ["mass_matrix"], cache_dir=tmp_path)
    q = np.array([0.3, -0.4])
    expected = np.asarray(dyn.mass_matrix(q))
    text = dyn.path.read_text()
    for broken in (text[: len(text) // 2], text.replace("jnp.where", "jnp.wehre", 1), "", "\x00\xff garbage"):
        dyn.path.write_text(broken)
        again = jaxskid.lower(robot, ["mass_matrix"], cache_dir=tmp_path)
        np.testing.assert_allclose(np.asarray(again.mass_matrix(q)), expected, rtol=1e-14)
        assert again.path.read_text() == text


def test_two_processes_writing_the_same_entry(tmp_path):
    script = textwrap.dedent(f"""
        import jax, numpy as np, jaxskid
        jax.config.update("jax_enable_x64", True)
        robot = jaxskid.load({str(ROBOT)!r})
        dyn = jaxskid.lower(robot, ["inverse_dynamics"], cache_dir={str(tmp_path)!r})
        print(float(dyn.inverse_dynamics(np.array([0.1, 0.2]), np.zeros(2), np.zeros(2))[0]))
    """)
    procs = [subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-500:] for o in outs]
    values = [float(o[0].strip()) for o in outs]
    assert values[0] == values[1]
    entries = list(tmp_path.glob("*.py"))
    assert len(entries) == 1 and not list(tmp_path.glob("*.tmp"))
    robot = jaxskid.load(ROBOT)
    reread = jaxskid.lower(robot, ["inverse_dynamics"], cache_dir=tmp_path)
    assert reread.path == entries[0]


def test_lowering_derived_equations_shares_the_robots_entry(tmp_path):
    robot = jaxskid.load(ROBOT)
    eqs = jaxskid.derive(robot, ["mass_matrix", "gravity_torques"])
    from_eqs = jaxskid.lower(eqs, cache_dir=tmp_path)  # printed from the equations, nothing derived again
    assert from_eqs.quantities == ("mass_matrix", "gravity_torques")
    from_robot = jaxskid.lower(robot, ["gravity_torques", "mass_matrix"], cache_dir=tmp_path)
    assert from_robot.path == from_eqs.path and from_robot.source == from_eqs.source
    subset = jaxskid.lower(eqs, "gravity_torques", cache_dir=tmp_path)
    q = np.array([0.3, -0.4])
    np.testing.assert_allclose(np.asarray(subset.gravity_torques(q)), np.asarray(from_robot.gravity_torques(q)),
                               rtol=1e-14)
    for bad, match in (({"quantities": ["coriolis_matrix"]}, "not derived"), ({"symbolic": ["m1"]}, "needs a Robot"),
                       ({"options": jaxskid.Options(cse="sympy")}, "differ")):
        with pytest.raises(jaxskid.RequestError, match=match):
            jaxskid.lower(eqs, **bad)


def test_entry_of_another_request_is_not_used(tmp_path):
    """An intact entry whose key is not the request's (same short file name) is regenerated, not run."""
    robot = jaxskid.load(ROBOT)
    dyn = jaxskid.lower(robot, ["mass_matrix"], cache_dir=tmp_path)
    text = dyn.path.read_text()
    module, _, _ = text.partition("# jaxskid-key: ")
    dyn.path.write_text(seal(module.replace("def mass_matrix(", "def mass_matrix_stale("), "0" * 64))
    again = jaxskid.lower(robot, ["mass_matrix"], cache_dir=tmp_path)
    assert again.path.read_text() == text
    np.testing.assert_allclose(np.asarray(again.mass_matrix(np.array([0.3, -0.4]))),
                               np.asarray(dyn.mass_matrix(np.array([0.3, -0.4]))), rtol=1e-14)
