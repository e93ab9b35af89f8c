"""Strict JAX settings for every test: float64, and no silent rank promotion."""

import os
import sys
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """Generated modules go to a fresh cache directory, so tests never depend on ~/.cache."""
    path = tmp_path_factory.mktemp("jaxskid-cache")
    old = os.environ.get("JAXSKID_CACHE_DIR")
    os.environ["JAXSKID_CACHE_DIR"] = str(path)
    yield path
    if old is None:
        os.environ.pop("JAXSKID_CACHE_DIR", None)
    else:
        os.environ["JAXSKID_CACHE_DIR"] = old
