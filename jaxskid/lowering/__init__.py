"""Lowering without SymPy: the on-disk cache of generated modules (keys, checksummed entries, atomic
writes), the loader that turns a generated module's text into its functions, and the build of generated C
into a native library (cffi or ctypes)."""

from ._cache import cache_dir, load_module, request_key
from ._native import BuildError, build
