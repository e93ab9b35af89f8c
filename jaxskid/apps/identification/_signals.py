"""From sampled joint positions to the states of identification: filtering and differentiation.

Identification needs ``(q, qd, qdd)`` where only ``q`` is measured (encoders, quantised and noisy). Two
estimators, both without phase lag:

- ``"butterworth"``: zero-phase low-pass filtering (a Butterworth filter run forward and backward, scipy's
  ``sosfiltfilt``; Gautier, "Dynamic identification of robots with power model", ICRA 1997, and Gautier &
  Poignet 2001 choose the cutoff at several times the bandwidth of the motion), then central differences;
- ``"fourier"``: for a periodic excitation of known period (Swevers et al., IEEE T-RA 13(5), 1997), the
  least-squares fit of a finite Fourier series, differentiated analytically.

:func:`parallel_filter` applies one low-pass filter to the regressor and to the measured torques and
decimates both (Gautier's parallel filtering): ``tau = Y pi`` is linear and time-invariant in the samples, so
it survives the filter, while the torque noise above the cutoff and what ``Y`` from filtered positions
lacks of the torques drop out alike. :func:`quantize` simulates an encoder.
"""

from __future__ import annotations

import numpy as np

from ..._errors import IdentificationError, RequestError, ShapeError


def _scipy_signal():
    """``scipy.signal``, imported on first use: it adds about a second to ``import jaxskid`` otherwise."""
    import scipy.signal

    return scipy.signal


UNIFORM_RTOL = 1e-6
"""Sample intervals may differ from their mean by this fraction of it and still count as uniform."""


def _samples(t, x, who: str, name: str = "q") -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or x.ndim < 1 or x.shape[0] != t.shape[0]:
        raise ShapeError(f"{who}: expected t (N,) and {name} (N,) or (N, ...) with the same N, got t {t.shape} "
                         f"and {name} {x.shape}")
    for label, values in (("t", t), (name, x)):
        finite = np.isfinite(values.reshape(t.shape[0], -1)).all(axis=1)
        if not finite.all():
            raise IdentificationError(f"{who}: {label} has NaN or infinite values (first at sample "
                                      f"{int(np.argmin(finite))}); fill or cut the gaps first")
    return t, x


def _interval(t, who: str) -> float:
    """The sample interval of uniformly sampled, increasing times ``t`` (N,)."""
    if t.size < 2:
        raise IdentificationError(f"{who}: need at least 2 samples, got {t.size}")
    dt = np.diff(t)
    mean = (t[-1] - t[0]) / (t.size - 1)
    if not mean > 0 or np.max(np.abs(dt - mean)) > UNIFORM_RTOL * mean:
        k = int(np.argmax(np.abs(dt - mean)))
        raise IdentificationError(f"{who}: expected uniformly sampled, increasing t; interval {k} is {dt[k]:.6g} s "
                                  f"against a mean of {mean:.6g} s (resample first)")
    return float(mean)


def _butterworth(t, cutoff, order: int, who: str, decimate: int = 1):
    """Second-order sections of the low-pass filter, checked against the samples ``t`` (the Nyquist frequency
    of every ``decimate``-th sample)."""
    dt = _interval(t, who)
    nyquist = 0.5 / dt / decimate
    if cutoff is None:
        raise RequestError(f"{who}: give cutoff= (Hz), the low-pass filter's cutoff frequency, below the Nyquist "
                           f"frequency {nyquist:.6g} Hz")
    if not 0 < cutoff < nyquist:
        raise RequestError(f"{who}: cutoff {cutoff} Hz must lie between 0 and the Nyquist frequency "
                           f"{nyquist:.6g} Hz of the {'decimated ' if decimate > 1 else ''}samples")
    if int(order) != order or order < 1:
        raise RequestError(f"{who}: order must be a positive integer, got {order}")
    sos = _scipy_signal().butter(int(order), cutoff, btype="low", fs=1.0 / dt, output="sos")
    padlen = 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))
    if t.size <= padlen:
        raise IdentificationError(f"{who}: a Butterworth filter of order {order} run forward and backward needs "
                                  f"more than {padlen} samples, got {t.size}")
    return sos


def lowpass(t, x, *, cutoff: float, order: int = 4) -> np.ndarray:
    """Zero-phase low-pass filtering of ``x (N, ...)`` sampled at uniform times ``t (N,)`` along its first axis:
    a Butterworth filter of ``order`` and ``cutoff`` (Hz) run forward and backward (``scipy.signal.sosfiltfilt``;
    the magnitude response is the filter's squared, the phase zero)."""
    t, x = _samples(t, x, "lowpass", "x")
    return _filtfilt(_butterworth(t, cutoff, order, "lowpass"), x, cutoff * (t[-1] - t[0]) / (t.size - 1))


EDGE_FIT = 0.25
"""The ends are extended by the quadratic fitted to their last ``EDGE_FIT / (cutoff dt)`` samples."""
EDGE_PAD = 3.0
"""... over ``EDGE_PAD / (cutoff dt)`` samples, where the filter's start-up transient dies out."""


def _filtfilt(sos, x, cutoff_dt: float):
    """``sosfiltfilt`` of ``x`` along axis 0, its ends extended by the quadratics that fit them best.

    scipy's default extension (odd, 3 (2 sections + 1) samples) keeps the value and slope at the ends but
    flips the curvature: measured on a sum of sines (1 kHz, cutoff 5 Hz, order 4, qdd from the filtered and
    differentiated signal), the error of qdd over the whole record fell from 5.3e-2 to 4.8e-3 of its RMS with
    these quadratics, and the samples near the ends beyond 1e-2 from about 500 to 160 at each end."""
    n = x.shape[0]
    fit = int(min(n, max(3, round(EDGE_FIT / cutoff_dt))))
    pad = int(max(1, round(EDGE_PAD / cutoff_dt)))
    steps = np.arange(fit, dtype=float)
    flat = x.reshape(n, -1)

    def extension(end):  # end[-1] is the outermost sample; the next ``pad`` along the quadratic
        coef = np.polynomial.polynomial.polyfit(steps, end, 2)
        return np.polynomial.polynomial.polyval(fit - 1 + np.arange(1, pad + 1, dtype=float), coef).T

    padded = np.concatenate([extension(flat[:fit][::-1])[::-1], flat, extension(flat[-fit:])])
    return _scipy_signal().sosfiltfilt(sos, padded, axis=0, padtype=None)[pad:pad + n].reshape(x.shape)


def estimate_derivatives(t, q, *, method: str = "butterworth", cutoff: float | None = None, order: int = 4,
                         period: float | None = None, harmonics: int | None = None):
    """Filtered joint positions and their first two time derivatives from sampled positions.

    Args:
        t: sample times (N,), uniformly spaced for ``"butterworth"`` (any spacing for ``"fourier"``).
        q: measured positions (N,) or (N, n).
        method: ``"butterworth"``: :func:`lowpass` (``cutoff``, ``order``), then second-order central
            differences (one-sided at the ends), each derivative filtered again; ``"fourier"``: the
            least-squares fit of
            ``a_0 + sum_k a_k cos(k w t) + b_k sin(k w t)``, ``w = 2 pi / period``, ``k = 1..harmonics``
            (default: every harmonic below ``cutoff``), differentiated analytically.
        cutoff: the low-pass cutoff frequency in Hz (below the Nyquist frequency ``1 / (2 dt)``).
        order: the Butterworth filter's order (the forward-backward filter's is twice that).
        period: the excitation's period in seconds (``"fourier"``).
        harmonics: the number of harmonics fitted (``"fourier"``).

    Returns:
        ``(q, qd, qdd)``, each the shape of ``q``.

    Choose the cutoff well above the motion's highest frequency (5-10 times, Gautier 1997): the filter's
    gain is below one from about half the cutoff on. Filtering the derivatives again lowers the noise they get
    from differencing: on a sum of sines up to 1 Hz with encoder noise (1e-4 rad, 1 kHz, cutoff 5-20 Hz),
    1.3-1.6 times less error in qdd and 1.2 times in qd, away from the ends. The ends, about ``fs / cutoff``
    samples each, carry the filter's start-up error (qdd most); cut them, or record whole periods and use
    ``"fourier"``.

    Raises:
        IdentificationError: NaN in ``t`` or ``q``, non-uniform sampling (``"butterworth"``), too few samples
            for the filter or for the harmonics.
        RequestError: an unknown method, a missing or too high cutoff, a missing period.
    """
    who = "estimate_derivatives"
    t, q = _samples(t, q, who)
    if method == "butterworth":
        sos = _butterworth(t, cutoff, order, who)
        dt = (t[-1] - t[0]) / (t.size - 1)
        qf = _filtfilt(sos, q, cutoff * dt)
        qd = _filtfilt(sos, np.gradient(qf, dt, axis=0, edge_order=2), cutoff * dt)
        return qf, qd, _filtfilt(sos, np.gradient(qd, dt, axis=0, edge_order=2), cutoff * dt)
    if method == "fourier":
        return _fourier(t, q, cutoff, period, harmonics, who)
    raise RequestError(f"{who}: unknown method {method!r}; expected 'butterworth' or 'fourier'")


def _fourier(t, q, cutoff, period, harmonics, who: str):
    if period is None or not period > 0:
        raise RequestError(f"{who}: method 'fourier' needs the excitation's period= (s), got {period}")
    if harmonics is None:
        if cutoff is None:
            raise RequestError(f"{who}: method 'fourier' needs harmonics= or a cutoff= (Hz) that sets them")
        harmonics = int(np.floor(cutoff * period + 1e-9))
    if int(harmonics) != harmonics or harmonics < 1:
        raise RequestError(f"{who}: harmonics must be a positive integer, got {harmonics}")
    if t.size < 2 * harmonics + 2:
        raise IdentificationError(f"{who}: {harmonics} harmonics need more than {2 * harmonics + 1} samples, got "
                                  f"{t.size}")
    dt = np.min(np.diff(np.sort(t))) if t.size > 1 else 0.0
    if dt > 0 and harmonics / period >= 0.5 / dt:
        raise RequestError(f"{who}: harmonic {harmonics} ({harmonics / period:.6g} Hz) is above the Nyquist "
                           f"frequency {0.5 / dt:.6g} Hz of the samples")
    w = 2 * np.pi / period * np.arange(1, harmonics + 1)
    phase = np.outer(t, w)
    c, s = np.cos(phase), np.sin(phase)
    basis = np.concatenate([np.ones((t.size, 1)), c, s], axis=1)
    coef, *_ = np.linalg.lstsq(basis, q.reshape(t.size, -1), rcond=None)
    d1 = np.concatenate([np.zeros((t.size, 1)), -s * w, c * w], axis=1)
    d2 = np.concatenate([np.zeros((t.size, 1)), -c * w**2, -s * w**2], axis=1)
    return tuple((b @ coef).reshape(q.shape) for b in (basis, d1, d2))


def quantize(q, step: float) -> np.ndarray:
    """Positions as an encoder reports them: rounded to multiples of ``step`` (e.g. ``2 pi / counts``).

    The rounding error is uniform in ``[-step / 2, step / 2]`` for motions much larger than ``step``:
    standard deviation ``step / sqrt(12)``."""
    if not step > 0:
        raise RequestError(f"quantize: step must be positive, got {step}")
    return np.round(np.asarray(q, dtype=float) / step) * step


def parallel_filter(t, y, tau, *, cutoff: float, order: int = 4, decimate: int = 1):
    """Filter the regressor and the torques with the same zero-phase low-pass filter, then keep every
    ``decimate``-th sample: ``(t, y, tau)`` decimated.

    Args:
        t: uniform sample times (N,).
        y: the regressor at the samples (N, n, p) (or any (N, ...)).
        tau: the measured joint forces (N, n).
        cutoff: the cutoff in Hz, below the Nyquist frequency of the decimated samples ``1 / (2 decimate dt)``.
        order: the Butterworth filter's order.
        decimate: the decimation factor (1: filter only).
    """
    who = "parallel_filter"
    t, y = _samples(t, y, who, "y")
    _, tau = _samples(t, tau, who, "tau")
    if int(decimate) != decimate or decimate < 1:
        raise RequestError(f"{who}: decimate must be a positive integer, got {decimate}")
    sos = _butterworth(t, cutoff, order, who, int(decimate))
    keep = slice(None, None, int(decimate))
    cutoff_dt = cutoff * (t[-1] - t[0]) / (t.size - 1)
    return t[keep], _filtfilt(sos, y, cutoff_dt)[keep], _filtfilt(sos, tau, cutoff_dt)[keep]
