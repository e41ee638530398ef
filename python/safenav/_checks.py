"""Input validation shared by the Python API: every error names the bad value."""

from __future__ import annotations

import reprlib

import numpy as np

_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = _REPR.maxlong = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 4
_REPR.maxlevel = 3


def cut(value, limit: int = 80) -> str:
    """``repr(value)`` cut to at most ``limit`` characters, for error messages.

    A huge value (a 2-million-element list, a 50 MB string, an integer past
    Python's 4300-digit ``repr`` limit) never makes a huge message.
    """
    try:
        text = _REPR.repr(value)
    except (ValueError, RecursionError):      # int beyond sys.get_int_max_str_digits()
        text = (f"<integer of about {int(value.bit_length() * 0.30103) + 1} digits>" if isinstance(value, int)
                else f"<{type(value).__name__}>")
    return text if len(text) <= limit else text[:limit - 3] + "..."


def as_array(name: str, value, shape: tuple, *, allow_nan: bool = False) -> np.ndarray:
    """Return ``value`` as a C-contiguous float64 array of ``shape``.

    ``shape`` entries may be ``None`` (any size).  Raises ``ValueError`` that
    names ``name``, the expected and the actual shape, or the first
    non-finite entry.
    """
    try:
        arr = np.asarray(value)
        complex_ = np.iscomplexobj(arr)
        if not complex_:
            arr = np.ascontiguousarray(arr, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {cut(value)}") from exc
    if complex_:        # numpy would drop the imaginary part with only a warning
        raise ValueError(f"{name} must be real, got complex values {cut(value)}")
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    bad = ~np.isfinite(arr)
    if allow_nan:
        bad &= ~np.isnan(arr)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        where = idx[0] if len(idx) == 1 else idx
        raise ValueError(f"{name}[{where}] = {arr[idx]} is not finite")
    return arr


INT32_MAX = 2**31 - 1      #: the largest C++ ``int``: ids and counts that reach the core


def as_int(name: str, value, lo: int = 1, hi: int | None = INT32_MAX) -> int:
    """``value`` as an int in [``lo``, ``hi``] (default: positive, up to the
    largest C++ ``int``; ``hi = None``: no upper bound), else a ``ValueError``
    that names it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        kind = "a positive integer" if lo == 1 else f"an integer >= {lo}"
        raise ValueError(f"{name} must be {kind}, got {cut(value)}")
    if hi is not None and value > hi:
        raise ValueError(f"{name} = {cut(value)} is too large (at most {hi})")
    return int(value)


def as_positive_int(name: str, value) -> int:
    """``value`` as an int >= 1 (callers check their own upper bound)."""
    return as_int(name, value, 1, None)


def as_seed(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0 or value >= 2**64:
        raise ValueError(f"{name} must be an integer in [0, 2**64), got {cut(value)}")
    return int(value)
