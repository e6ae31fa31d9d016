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
