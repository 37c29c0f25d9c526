"""One conversion of every path argument (file names given to the C++ side)."""

import os


def fspath(p, what="path"):
    """str, bytes or os.PathLike -> str, as Python's own open() takes them: bytes are decoded
    with the file-system encoding (surrogateescape), None and numbers are a TypeError, and a
    NUL byte is a ValueError (the C++ side would cut the name there and open another file)."""
    if p is None or isinstance(p, (bool, int, float)):
        raise TypeError("%s must be a str, bytes or os.PathLike, not %s" % (what, type(p).__name__))
    p = os.fspath(p)
    if isinstance(p, bytes):
        p = os.fsdecode(p)
    if "\x00" in p:
        raise ValueError("%s: embedded null byte" % what)
    return p
