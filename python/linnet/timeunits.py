"""Time units of trajectory files, judged from the magnitude of the first time stamp.

TUM files are meant to hold seconds, and EuRoC csv files integer nanoseconds, but files exported by other tools often
hold another unit. A wrong unit used to overflow (ns read as seconds) or give confusing ordering errors; these helpers
pick the unit from the first time stamp, so that both loaders (evaluation and simulator) read the same files the
same way:

    magnitude of the first time stamp    unit read
    >= 1e17                              ns  (Unix epoch in ns is ~1.4e18 for 2014)
    >= 1e14                              us  (epoch in us ~1.4e15)
    >= 1e11                              ms  (epoch in ms ~1.4e12; 1e11 s would be the year 5138)
    otherwise                            s   (epoch in s ~1.4e9, or time since the start of a recording)
"""
from __future__ import annotations

from decimal import ROUND_HALF_EVEN, Decimal, InvalidOperation

from linnet.fileio import InputError

#: (lower bound of |t|, unit name, ns per unit), largest first.
_UNITS = ((1e17, "ns", 1), (1e14, "us", 1_000), (1e11, "ms", 1_000_000), (0.0, "s", 1_000_000_000))


def unit_of(first_time: float) -> tuple:
    """(unit name, ns per unit) for a file whose first time stamp is `first_time`, by the table above."""
    magnitude = abs(first_time)
    for bound, name, scale in _UNITS:
        if magnitude >= bound:
            return name, scale
    return "s", 1_000_000_000


def euroc_seconds_hint(first_time: float) -> str:
    """A hint for a EuRoC csv (nanoseconds expected) whose time stamps look like another unit, or ""."""
    name, _ = unit_of(first_time)
    if name == "ns":
        return ""
    return f" (time stamps look like {name}; a EuRoC csv holds integer nanoseconds)"


def parse_time_ns(path, number: int, token: str, scale: int) -> int:
    """Exact conversion of a decimal time token to int64 ns (``scale``: ns per file unit, 1e9 for seconds);
    InputError naming the file and line for a token that is not a finite number or out of the int64 ns range."""
    try:
        value = Decimal(token) * scale
    except InvalidOperation:
        raise InputError(f"{path}:{number}: bad time stamp '{token}'") from None
    if not value.is_finite():
        raise InputError(f"{path}:{number}: bad time stamp '{token}'")
    ns = int(value.to_integral_value(rounding=ROUND_HALF_EVEN))
    if abs(ns) >= 2**63:
        raise InputError(f"{path}:{number}: time stamp '{token}' is out of the int64 ns range")
    return ns
