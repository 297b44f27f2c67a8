"""Validation shared by the core's public functions."""

from __future__ import annotations

import operator

__all__ = ["whole_number"]


def whole_number(value: object, name: str, minimum: int = 0, *, even: bool = False) -> int:
    """``value`` as an ``int`` if it is a whole number (not a bool) of at least ``minimum``, else ValueError.

    Parameters
    ----------
    value : object
        Anything; numpy integers are accepted, floats and bools are not.
    name : str
        How the message names it, e.g. ``"samples"``.
    minimum : int
    even : bool
        Also require an even number.

    Returns
    -------
    int
    """
    kind = {0: "a non-negative integer", 1: "a positive integer"}.get(minimum, f"an integer of at least {minimum}")
    if even:
        kind = f"an even integer of at least {minimum}"
    if isinstance(value, bool):
        raise ValueError(f"{name} must be {kind}, got {value!r}")
    try:
        out = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be {kind}, got {value!r}") from None
    if out < minimum or (even and out % 2):
        raise ValueError(f"{name} must be {kind}, got {out}")
    return out
