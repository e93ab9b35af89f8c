"""Independent references for jaxskid's tests and benchmarks: the derived program evaluated at high
precision with mpmath (``_reference``), and a numeric recursive (Newton–Euler, CRBA) evaluation in JAX that
shares no code path with the closed form but the spatial algebra (``_recursive``)."""
