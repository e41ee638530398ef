"""Input validation for the whole Python layer: every error names the bad value.

Two message forms, one per kind of input:

* arguments of the API: ``n_particles must be a positive integer, got 0``
  (:func:`as_array`, :func:`integer`, :func:`as_seed`);
* fields of a world or scenario: ``obstacles[3].radius = -2.0: must be in
  (0, 100000]`` — the field's path, its value, the problem — raised as a
  :class:`ScenarioError` (:func:`fail`, :func:`real`, :func:`integer` with
  ``field=True``, :func:`text`, :func:`vector`, :func:`items`, :func:`table`);
  :class:`at` prefixes the path of the enclosing object.

The limits on world and scenario inputs live here too (docs/scenario.md gives
the reasons): no file, however large its numbers or lists, hangs validation
or planning.
"""

from __future__ import annotations

import argparse
import math
import reprlib
from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = [
    "ScenarioError", "cut", "as_array", "integer", "as_positive_int", "as_seed", "join", "at", "fail", "Range",
    "interval", "real", "text", "vector", "items", "table", "INT32_MAX", "MAX_COORDINATE", "FIELD_SIZE",
    "MAX_RADIUS", "MAX_OBSTACLES", "MAX_HAZARDS", "MAX_LANDMARKS", "MAX_VERTICES", "MAX_PATH_CLUSTERS", "MAX_NAME",
    "arg_probability", "arg_positive", "arg_at_least",
]

INT32_MAX = 2**31 - 1      #: the largest C++ ``int``: ids and counts that reach the core

MAX_COORDINATE = 1e6         #: |x|, |y|, |z| of every point [m]
FIELD_SIZE = (1.0, 1e5)      #: the field's width and height [m]
MAX_RADIUS = 1e5             #: of a circle [m]
MAX_OBSTACLES = 1000
MAX_HAZARDS = 1000
MAX_LANDMARKS = 10_000
MAX_VERTICES = 1000          #: of one polygon
MAX_PATH_CLUSTERS = 100      #: clusters on one path type
MAX_NAME = 200               #: characters of a name or a landmark class


class ScenarioError(ValueError):
    """A world or scenario field is invalid; the message names the field and its value."""


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


# --------------------------------------------------------------------------- API arguments

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


def integer(name: str, value, lo: int = 1, hi: int | None = INT32_MAX, *, field: bool = False) -> int:
    """``value`` as an int in [``lo``, ``hi``] (default: positive, up to the
    largest C++ ``int``; ``hi = None``: no upper bound); bools, floats and
    strings are refused.

    The error names ``name``: ``n must be a positive integer, got 0`` (``n =
    2147483648 is too large (at most 2147483647)``), or with ``field=True``
    the field form ``n = 0: must be in [1, 10]`` as a :class:`ScenarioError`.
    """
    is_int = not isinstance(value, bool) and isinstance(value, (int, np.integer))
    if is_int and value >= lo and (hi is None or value <= hi):
        return int(value)
    if field:
        fail(name, value, f"must be in [{lo}, {hi}]" if is_int else "must be an integer")
    if is_int and value >= lo:
        raise ValueError(f"{name} = {cut(value)} is too large (at most {hi})")
    kind = "a positive integer" if lo == 1 else f"an integer >= {lo}"
    raise ValueError(f"{name} must be {kind}, got {cut(value)}")


def as_positive_int(name: str, value) -> int:
    """``value`` as an int >= 1 (callers check their own upper bound)."""
    return integer(name, value, 1, None)


def choice(name: str, value, table: dict):
    """``table[value]``, or a ValueError naming ``name``, the value and the choices."""
    try:
        return table[value]
    except (KeyError, TypeError):
        raise ValueError(f"{name} = {value!r}: must be one of {sorted(table)}") from None


def as_seed(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0 or value >= 2**64:
        raise ValueError(f"{name} must be an integer in [0, 2**64), got {cut(value)}")
    return int(value)


# --------------------------------------------------------------------------- world and scenario fields

def join(prefix: str, msg: str) -> str:
    """``msg`` (a field path, a ``[i]`` suffix or a ``= value: problem`` tail) under the path ``prefix``."""
    if not prefix:
        return msg
    if msg.startswith("["):
        return prefix + msg
    if msg.startswith(("=", ":")):
        return f"{prefix} {msg}" if msg.startswith("=") else prefix + msg
    return f"{prefix}.{msg}"


class at:
    """Context manager: re-raise a ``ValueError`` with ``prefix`` prepended to its field path."""

    def __init__(self, prefix: str):
        self.prefix = prefix

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None and issubclass(exc_type, ValueError):
            raise ScenarioError(join(self.prefix, str(exc))) from None
        return False


def fail(name: str, value, problem: str):
    """Raise ``ScenarioError("name = value: problem")``."""
    raise ScenarioError(f"{name} = {cut(value)}: {problem}")


def interval(lo: float, hi: float, lo_open: bool = False) -> str:
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"


@dataclass(frozen=True)
class Range:
    """The valid values of a scalar parameter: ``[lo, hi]`` (``(lo, hi]`` if ``lo_open``); ``integer`` for counts."""

    lo: float
    hi: float
    lo_open: bool = False
    integer: bool = False

    def check(self, name: str, value):
        if self.integer:
            return integer(name, value, int(self.lo), int(self.hi), field=True)
        return real(name, value, lo=self.lo, lo_open=self.lo_open, hi=self.hi)

    def __str__(self) -> str:
        return f"[{int(self.lo)}, {int(self.hi)}]" if self.integer else interval(self.lo, self.hi, self.lo_open)


def real(name: str, value, *, lo: float, hi: float, lo_open: bool = False) -> float:
    """``value`` as a finite float (ints accepted, bools and strings not) in ``[lo, hi]`` (``(lo, hi]``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        fail(name, value, "must be a number")
    try:
        v = float(value)
    except OverflowError:                       # an integer too large for a float
        v = math.inf if value > 0 else -math.inf
    if not math.isfinite(v):
        fail(name, value, "must be finite")
    if not (lo < v <= hi if lo_open else lo <= v <= hi):
        fail(name, value, f"must be in {interval(lo, hi, lo_open)}")
    return v


def text(name: str, value, max_len: int = MAX_NAME) -> str:
    if not isinstance(value, str) or not value.strip():
        fail(name, value, "must be a non-empty string")
    if len(value) > max_len:
        fail(name, value, f"has {len(value)} characters, at most {max_len} allowed")
    return value


def vector(name: str, value, sizes: tuple[int, ...], bound: float = MAX_COORDINATE) -> tuple[float, ...]:
    """A list of ``sizes`` numbers, each in [-bound, bound]."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        fail(name, value, f"must be a list of {' or '.join(map(str, sizes))} numbers")
    if len(value) not in sizes:
        fail(name, value, f"must have {' or '.join(map(str, sizes))} entries, got {len(value)}")
    return tuple(real(f"{name}[{i}]", v, lo=-bound, hi=bound) for i, v in enumerate(value))


def items(name: str, value, max_len: int) -> tuple:
    """``value`` as a tuple: a list of at most ``max_len`` entries."""
    if isinstance(value, (str, bytes, dict)) or not isinstance(value, (Sequence, np.ndarray)):
        fail(name, value, "must be a list")
    if len(value) > max_len:
        fail(name, value, f"has {len(value)} entries, at most {max_len} allowed")
    return tuple(value)


def table(name: str, value, *, required: Sequence[str], optional: Sequence[str]) -> dict:
    """Check that ``value`` is a mapping with exactly the allowed keys."""
    if not isinstance(value, dict):
        raise ScenarioError(join(name, f"= {cut(value)}: must be a table"))
    allowed = set(required) | set(optional)
    for k in value:
        if k not in allowed:
            # a key that is not a plain name (a newline, a number, …) is quoted, so the error stays one line
            key = str(k) if isinstance(k, str) and k.isidentifier() else cut(k, 40)
            where = join(name, key if len(key) <= 40 else key[:37] + "...")
            raise ScenarioError(f"{where} = {cut(value[k])}: unknown key (allowed: {', '.join(sorted(allowed))})")
    for k in required:
        if k not in value:
            raise ScenarioError(f"{join(name, k)}: missing (required: {', '.join(required)})")
    return value


def declared(settings_type, **values):
    """A core settings struct (any with ``set_param``) with ``values`` set
    through its parameter declarations: each value is checked against its
    declared range and type, and an error names it (``ValueError`` out of
    range, ``TypeError`` of the wrong type)."""
    out = settings_type()
    for name, value in values.items():
        out.set_param(name, value.item() if isinstance(value, np.generic) else value)
    return out


# --------------------------------------------------------------------------- command-line types

def arg_probability(text: str) -> float:
    """An argparse type: a probability in [0, 1]."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"must be a probability in [0, 1], got {text}")
    return v


def arg_positive(text: str) -> float:
    """An argparse type: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (np.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {text}")
    return v


def arg_at_least(lo: int):
    """An argparse type: an integer >= ``lo`` (the range checked by :func:`safenav.validation.integer`,
    the message in argparse's words)."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        try:
            return integer(text, v, lo, None)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer >= {lo}, got {v}") from None
    return parse
