"""One check of the public functions' arguments other than paths (_paths.py) and traced arrays
(_arrays.py): a wrong type or value is a short TypeError or ValueError naming the function, the
argument and what it takes ("camera_rays: width must be an integer in [1, 16384], got 2.5"),
raised before the C++ module sees it (pybind11 answers a wrong type with its list of signatures,
or cuts 2.5 to 2 without a word). `where` is "function: argument" in every helper."""

import operator

import numpy as np


def _got(value):
    text = repr(value)
    return text if len(text) <= 60 else type(value).__name__


def integer(value, where, lo, hi=None, none=None, expected=None):
    """`value` as an int in [lo, hi] (hi None: no upper bound). Python and numpy integers only: a
    bool, a float (2.5) or a str ('2') is a TypeError, an integer out of range a ValueError.
    None is allowed when `none` is not None, and gives `none`."""
    if value is None and none is not None:
        return none
    if expected is None:
        expected = ("None or " if none is not None else "") + (
            "an integer in [%d, %d]" % (lo, hi) if hi is not None else "an integer >= %d" % lo)
    try:
        if isinstance(value, (bool, np.bool_)):
            raise TypeError
        number = operator.index(value)
    except TypeError:
        raise TypeError("%s must be %s, got %s" % (where, expected, _got(value))) from None
    if number < lo or (hi is not None and number > hi):
        raise ValueError("%s must be %s, got %d" % (where, expected, number))
    return number


def flag(value, where):
    """`value` as a bool: True or False (numpy bools too). Anything else is a TypeError: Python's
    truthiness would read deep="no" or any_hit="false" as True."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError("%s must be True or False, got %s" % (where, _got(value)))
    return bool(value)


def number(value, where):
    """`value` as a float: Python and numpy real numbers, not a bool, a str or None."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or value is None:
        raise TypeError("%s must be a number, got %s" % (where, _got(value)))
    try:
        return float(value)
    except (TypeError, ValueError):
        raise TypeError("%s must be a number, got %s" % (where, _got(value))) from None


def text(value, where, none=None):
    """`value`, a str (None gives `none` when that is not None)."""
    if value is None and none is not None:
        return none
    if not isinstance(value, str):
        raise TypeError("%s must be a str%s, got %s" % (where, " or None" if none is not None else "",
                                                        _got(value)))
    return value


def floats(value, where, shape, dtype=np.float32):
    """`value` as a `dtype` array (numpy's conversion, no copy when it already is one) of `shape`,
    a tuple of one or more extents, None for any ((None, 3): N rows of 3). What numpy cannot read
    as numbers, and a single value (None, which numpy reads as NaN, or one number), is a
    TypeError; another shape a ValueError."""
    wanted = "(%s%s)" % (", ".join("N" if s is None else str(s) for s in shape), "," if len(shape) == 1 else "")
    try:
        array = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as e:
        raise TypeError("%s must be an array of shape %s of numbers (%s)" % (where, wanted, e)) from None
    if array.ndim == 0:
        raise TypeError("%s must be an array of shape %s, got %s" % (where, wanted, type(value).__name__))
    if array.ndim != len(shape) or any(s is not None and s != got for s, got in zip(shape, array.shape)):
        raise ValueError("%s must have shape %s, got %s" % (where, wanted, array.shape))
    return array


def scene_handle(scene, where):
    """The open Scene's handle (ValueError once it is closed): `scene` must be a cwbvh.Scene."""
    handle = getattr(scene, "_handle", None)
    if not callable(handle):
        raise TypeError("%s must be a cwbvh.Scene (from cwbvh.open), got %s" % (where, type(scene).__name__))
    return handle()
