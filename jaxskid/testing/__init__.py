"""Independent references for jaxskid's tests and benchmarks: the derived program evaluated at high
precision with mpmath (``_reference``), a numeric recursive (Newton–Euler, CRBA) evaluation in JAX that
shares no code path with the closed form but the spatial algebra (``_recursive``), and exact symbolic
comparison of two closed forms (``_symbolic``: :func:`closed_form`, :func:`vanishes`)."""

from ._symbolic import closed_form, vanishes

__all__ = ["closed_form", "vanishes"]
