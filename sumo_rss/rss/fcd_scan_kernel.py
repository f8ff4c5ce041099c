"""The compiled loops of :mod:`.fcd_scan`: one pass over a time step's bytes that checks it is exactly SUMO's layout
and finds where every attribute value lies, and the exact conversion of plain decimals (``-12.345600``) to floats.

A decimal of at most 15 digits and 22 after the point is converted as (its digits as an integer) / 10^(digits after
the point): both are exact doubles and IEEE division rounds correctly, so the result is the double nearest to the
decimal, which is what Python's ``float`` and numpy give (Clinger's fast path). Any other form is left to them.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel

# Where a layout's literal pieces are in the array handed to scan_step, in order: the step's start tag up to its
# time, the rest of that tag, one piece before each attribute value ('<vehicle id="', '" x="', ...), the end of a
# vehicle ('"/>') and the step's end tag.
STEP_OPEN, STEP_OPEN_END, FIRST_ATTRIBUTE = 0, 1, 2
MAX_DIGITS = 15  # below 2^53: the digits as an integer are an exact double
EXACT_POWERS = np.array([10.0 ** k for k in range(23)])  # 1e0 ... 1e22, each an exact double


@kernel
def scan_step(text, literals, starts):
    """``text`` (uint8): white space, then one ``<timestep time="...">`` element of self-closed vehicles whose
    attributes are those of ``literals`` (uint8; piece k is ``literals[starts[k]:starts[k + 1]]``, in the order
    above), separated by XML white space, every value without '"', '&', '<', control or non-ASCII bytes. Returns
    (vehicles, where the time value starts, where it ends, [vehicles, attributes, 2] start and end of each value);
    vehicles = -1 where ``text`` is not exactly that."""
    n = text.size
    pieces = starts.size - 1
    attributes = pieces - 4
    vehicle_end, step_end = pieces - 2, pieces - 1
    shortest = 1
    for k in range(FIRST_ATTRIBUTE, step_end):
        shortest += starts[k + 1] - starts[k]
    offsets = np.empty((n // shortest + 1, max(attributes, 0), 2), dtype=np.int64)
    fail = (-1, 0, 0, offsets[:0])
    i = _skip_space(text, 0)
    i = _literal(text, i, literals, starts, STEP_OPEN)
    if i < 0:
        return fail
    time_start = i
    i = _value_end(text, i)
    if i < 0:
        return fail
    time_end = i
    i = _literal(text, i, literals, starts, STEP_OPEN_END)
    count = 0
    while i >= 0:
        i = _skip_space(text, i)
        after = _literal(text, i, literals, starts, FIRST_ATTRIBUTE)
        if after < 0:
            break
        i = after
        for a in range(attributes):
            if a:
                i = _literal(text, i, literals, starts, FIRST_ATTRIBUTE + a)
                if i < 0:
                    return fail
            offsets[count, a, 0] = i
            i = _value_end(text, i)
            if i < 0:
                return fail
            offsets[count, a, 1] = i
        i = _literal(text, i, literals, starts, vehicle_end)
        if i < 0:
            return fail
        count += 1
    if i < 0:
        return fail
    i = _literal(text, i, literals, starts, step_end)
    if i != n:
        return fail
    return count, time_start, time_end, offsets[:count]


@kernel
def _skip_space(text, i):
    while i < text.size and (text[i] == 32 or text[i] == 9 or text[i] == 10 or text[i] == 13):
        i += 1
    return i


@kernel
def _literal(text, i, literals, starts, piece):
    """The position after piece ``piece`` of ``literals`` if ``text`` has it at ``i``, else -1."""
    if i < 0:
        return -1
    length = starts[piece + 1] - starts[piece]
    if i + length > text.size:
        return -1
    for k in range(length):
        if text[i + k] != literals[starts[piece] + k]:
            return -1
    return i + length


@kernel
def _value_end(text, i):
    """The position of the '"' that ends the attribute value starting at ``i``; -1 where a byte before it is one
    expat would not give as written (a reference, '<', a control character) or not ASCII."""
    while i < text.size:
        c = text[i]
        if c == 34:
            return i
        if c == 38 or c == 60 or c < 32 or c > 127:
            return -1
        i += 1
    return -1


@kernel
def exact_decimals(text, bounds):
    """The values ``text[bounds[j, 0]:bounds[j, 1]]`` (uint8) as floats, and whether every one is a plain decimal
    (an optional '-', digits with at most one '.', at most MAX_DIGITS digits, at most 22 after the point) converted
    exactly; where one is not, the floats are not to be used."""
    out = np.empty(bounds.shape[0])
    for j in range(bounds.shape[0]):
        i, end = bounds[j, 0], bounds[j, 1]
        negative = i < end and text[i] == 45
        if negative:
            i += 1
        digits = 0
        after = -1  # digits after the point (-1: no point)
        mantissa = 0
        while i < end:
            c = text[i]
            if c == 46 and after < 0:
                after = 0
            elif 48 <= c <= 57:
                mantissa = mantissa * 10 + (c - 48)
                digits += 1
                if after >= 0:
                    after += 1
            else:
                return out, False
            i += 1
        if digits == 0 or digits > MAX_DIGITS or after > 22:
            return out, False
        value = mantissa / EXACT_POWERS[max(after, 0)]
        out[j] = -value if negative else value
    return out, True
