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
    # a robot's request brings the quantities' pullbacks (for reverse mode): the same equations
    names = ("mass_matrix", "gravity_torques", "mass_matrix_vjp", "gravity_torques_vjp")
    eqs = jaxskid.derive(robot, names)
    from_eqs = jaxskid.lower(eqs, cache_dir=tmp_path)  # printed from the equations, nothing derived again
    assert from_eqs.quantities == names
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


_FIRST_CALL = """
import sys, jax, numpy as np
jax.config.update("jax_enable_x64", True)
hits = []
jax.monitoring.register_event_listener(lambda event, **kw: hits.append(event) if event.endswith("cache_hits") else None)
import jaxskid
robot = jaxskid.load(sys.argv[1])
dyn = jaxskid.lower(robot, ["forward_dynamics"], cache_dir=sys.argv[2])
x = jaxskid.rollout(dyn, np.array([0.3, -0.2, 0.0, 0.0]), np.zeros((20, 2)), 1e-3, 20).x
print(len(hits), float(x[-1, 0]))
"""


def _first_call(tmp_path, **env):
    import os

    # a small robot compiles fast: every program is written, whatever its compile time
    environ = {**os.environ, "JAXSKID_CACHE_DIR": str(tmp_path / "home"), "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0",
               **env}
    environ.pop("JAX_COMPILATION_CACHE_DIR", None) if "JAX_COMPILATION_CACHE_DIR" not in env else None
    done = subprocess.run([sys.executable, "-c", _FIRST_CALL, str(ROBOT), str(tmp_path / "modules")],
                          capture_output=True, text=True, timeout=600, env=environ)
    assert done.returncode == 0, done.stderr[-2000:]
    hits, value = done.stdout.split()
    return int(hits), float(value)


def test_compiled_programs_survive_the_process(tmp_path):
    """The first process compiles and writes jaxskid.cache_dir()/xla; a second one reads its programs there
    (JAX's cache-hit events) and computes the same trajectory."""
    hits, first = _first_call(tmp_path)
    assert hits == 0
    assert any((tmp_path / "home" / "xla").iterdir()), "nothing was written to the compilation cache"
    hits, second = _first_call(tmp_path)
    assert hits > 0 and second == first


def test_compilation_cache_can_be_turned_off_or_left_to_jax(tmp_path):
    hits, _ = _first_call(tmp_path, JAXSKID_COMPILATION_CACHE="0")
    assert hits == 0 and not (tmp_path / "home" / "xla").exists()
    own = tmp_path / "jax-own"
    _first_call(tmp_path, JAX_COMPILATION_CACHE_DIR=str(own))
    assert any(own.iterdir()) and not (tmp_path / "home" / "xla").exists(), "the user's own JAX cache is used"


def test_compilation_cache_function(tmp_path):
    import jax

    from jaxskid.lowering import _xla_cache

    before = jax.config.jax_compilation_cache_dir
    try:
        assert jaxskid.compilation_cache(tmp_path / "xla") == tmp_path / "xla"
        assert jax.config.jax_compilation_cache_dir == str(tmp_path / "xla")
        assert jaxskid.compilation_cache(None) is None and jax.config.jax_compilation_cache_dir is None
        assert _xla_cache.default_compilation_cache() is None, "turned off stays off"
    finally:
        jaxskid.compilation_cache(before or None)


def test_classic_emitters_flag_at_import():
    """Importing jaxskid before JAX starts puts the classic CPU emitters in XLA_FLAGS, so that a plain
    jax.jit compiles jaxskid's programs as jaxskid.jit does; a user's own setting of the flag is kept."""
    import os

    script = "import os, jaxskid, jax; jax.devices(); print(os.environ.get('XLA_FLAGS', ''))"
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert out.stdout.split() == ["--xla_cpu_use_fusion_emitters=false"], out.stderr[-1000:]
    env["XLA_FLAGS"] = "--xla_cpu_use_fusion_emitters=true"
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert out.stdout.split() == ["--xla_cpu_use_fusion_emitters=true"], out.stderr[-1000:]


def test_no_classic_emitters_switch_where_xla_lacks_it(monkeypatch):
    """jaxlib 0.11's XLA has no switch to the classic CPU emitters and aborts the process at an unknown flag
    in XLA_FLAGS: there jaxskid adds no flag and passes no compiler option."""
    import os

    import jaxlib.version

    from jaxskid import _xla_flags, compiler_options

    monkeypatch.setattr(jaxlib.version, "__version__", "0.11.2")
    monkeypatch.delenv("XLA_FLAGS", raising=False)
    assert not _xla_flags.classic_emitters_switch()
    assert compiler_options() == {}
    monkeypatch.setattr("jax._src.xla_bridge.backends_are_initialized", lambda: False)
    assert _xla_flags.prefer_classic_emitters() is False
    assert "XLA_FLAGS" not in os.environ
    monkeypatch.setattr(jaxlib.version, "__version__", "0.10.2")
    assert _xla_flags.classic_emitters_switch() and compiler_options() == {"xla_cpu_use_fusion_emitters": False}


def test_synchronous_cpu_dispatch_when_asked_for():
    """With JAXSKID_SYNC_DISPATCH=1, importing jaxskid's runtime before JAX's backends start turns JAX's
    asynchronous CPU dispatch off (benchmarks/threads.py: a loaded machine made every hand-over wait); without
    it JAX's default stays, and a process whose backends started first keeps what it had."""
    import os

    probe = "from jax._src import xla_bridge; print(xla_bridge._CPU_ENABLE_ASYNC_DISPATCH.value)"
    scripts = {
        "import jaxskid.runtime._jit; " + probe: "False",
        "import jax; jax.devices(); import jaxskid.runtime._jit; " + probe: "True",
    }
    env = {**os.environ, "JAXSKID_SYNC_DISPATCH": "1"}
    for script, expected in scripts.items():
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
        assert out.stdout.split() == [expected], (script, out.stderr[-1000:])
    out = subprocess.run([sys.executable, "-c", next(iter(scripts))], capture_output=True, text=True,
                         env={k: v for k, v in os.environ.items() if k != "JAXSKID_SYNC_DISPATCH"}, timeout=300)
    assert out.stdout.split() == ["True"], out.stderr[-1000:]


def test_freed_memory_kept_when_asked_for():
    """With JAXSKID_MALLOC=keep, importing jaxskid makes glibc serve a large block from its heap (no mmap of its
    own: glibc's count of mmapped blocks stays 0 while a 64 MB array lives) and a JAX computation runs; without
    it, glibc's default stays (the array is one mmapped block)."""
    import os

    script = (
        "import ctypes, numpy as np, jaxskid, jax.numpy as jnp\n"
        "class Info(ctypes.Structure):\n"
        "    _fields_ = [(n, ctypes.c_size_t) for n in ('arena ordblks smblks hblks hblkhd usmblks fsmblks '\n"
        "                                                'uordblks fordblks keepcost').split()]\n"
        "info = ctypes.CDLL('libc.so.6').mallinfo2\n"
        "info.restype = Info\n"
        "before = info().hblks\n"
        "big = np.ones(8 << 20)\n"
        "print(info().hblks - before, float(jnp.sum(jnp.asarray(big) * 2.0)))\n"
    )
    for value, blocks in (("keep", "0"), ("", "1")):
        env = {**os.environ, "JAXSKID_MALLOC": value}
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
        assert out.stdout.split() == [blocks, str(float(2 * (8 << 20)))], (value, out.stderr[-1000:])
