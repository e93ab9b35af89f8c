"""Strict JAX settings for every test (float64, no silent rank promotion), a private cache directory, and the
fixtures that several test files share. Shared robots, paths and error measures: tests/helpers.py."""

import os
import sys
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")

sys.path.insert(0, str(Path(__file__).parent))

import jaxskid  # noqa: E402  (after the JAX settings)
from helpers import FD, ROBOTS_DIR  # noqa: E402  (after tests/ is on sys.path)


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """Generated modules go to a fresh cache directory, so tests never depend on ~/.cache. The workers of
    one ``pytest -n`` run share it (entries and libraries are written atomically), so a robot's module is
    derived, and its programs compiled, once per run rather than once per worker."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        path = tmp_path_factory.getbasetemp().parent / "jaxskid-cache"  # the run's folder, shared by its workers
        path.mkdir(exist_ok=True)
    else:
        path = tmp_path_factory.mktemp("jaxskid-cache")
    old = os.environ.get("JAXSKID_CACHE_DIR")
    os.environ["JAXSKID_CACHE_DIR"] = str(path)
    yield path
    if old is None:
        os.environ.pop("JAXSKID_CACHE_DIR", None)
    else:
        os.environ["JAXSKID_CACHE_DIR"] = old


@pytest.fixture(scope="module")
def pendulum():
    """The double pendulum (robots/double_pendulum.yaml) and its lowered M and tau: (robot, dyn)."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml")
    return robot, jaxskid.lower(robot, FD)
