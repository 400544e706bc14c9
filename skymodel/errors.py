"""Errors raised by skymodel for bad input.

Every error names the parameter, the value that was given and what is allowed, so a
user (or the Blender panel, which shows the message as is) can fix the call without
reading the source.
"""

from __future__ import annotations

from typing import Any, Iterable


class SkymodelInputError(ValueError):
    """A parameter was outside its allowed range or set.

    Attributes
    ----------
    parameter : the name of the parameter as the user wrote it (``"month"``).
    value : the offending value.
    allowed : a short human description of what is allowed (``"1..12"``).
    """

    def __init__(self, parameter: str, value: Any, allowed: str):
        self.parameter = parameter
        self.value = value
        self.allowed = allowed
        super().__init__(f"{parameter}={value!r} is not allowed: expected {allowed}")


def check_range(parameter: str, value: float, low: float, high: float, unit: str = "") -> float:
    """Return ``value`` as float if ``low <= value <= high`` (and finite), else raise."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SkymodelInputError(parameter, value, f"a number in [{low}, {high}]{' ' + unit if unit else ''}") from None
    if not (low <= v <= high):  # also rejects NaN
        raise SkymodelInputError(parameter, value, f"a number in [{low}, {high}]{' ' + unit if unit else ''}")
    return v


def check_array_range(parameter: str, value, low: float, high: float, unit: str = ""):
    """``value`` as a float array if every element is finite and in ``[low, high]``, else raise
    naming ``parameter`` and the first offending element."""
    import numpy as np

    allowed = f"finite numbers in [{low:g}, {high:g}] {unit}".rstrip()
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SkymodelInputError(parameter, value, allowed) from None
    bad = ~np.isfinite(a) | (a < low) | (a > high)
    if np.any(bad):
        raise SkymodelInputError(parameter, float(np.atleast_1d(a)[np.atleast_1d(bad)][0]), allowed)
    return a


def check_choice(parameter: str, value: str, known: Iterable[str]) -> str:
    """Return ``value`` if it is one of ``known`` (case-insensitive), else raise listing the names."""
    names = list(known)
    lookup = {n.lower(): n for n in names}
    key = str(value).lower()
    if key not in lookup:
        raise SkymodelInputError(parameter, value, "one of: " + ", ".join(sorted(names)))
    return lookup[key]


def check_finite(name: str, array) -> None:
    """Raise ``FloatingPointError`` if ``array`` holds NaN or infinity (no NaN leaves the core silently)."""
    import numpy as np

    a = np.asarray(array)
    if not np.all(np.isfinite(a)):
        raise FloatingPointError(f"{name}: non-finite values produced ({np.count_nonzero(~np.isfinite(a))} of {a.size})")
