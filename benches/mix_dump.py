"""Reading the planes `method_mix --work` dumps.

`method_mix` writes each case's reference, input and method outputs as
`<case>-<W>x<H>-<name>.bin`: planar little-endian f32, R, G, B first (a
method's output then has its error estimate's R, G, B). Used by
`auto_oidn.py`, `auto_members.py`, `energy_classes.py` and
`fresh_sample_error.py`.
"""
import os
import sys

import numpy as np


def planes(path, n, count=None):
    """The planes of the dump at `path` of `n` pixels each, as an array of
    shape (planes, n) in f64: the first `count`, or all of them. Exits
    with the path in the message when the file is missing, is not whole
    planes, or holds non-finite values."""
    if not os.path.isfile(path):
        sys.exit(f"{path}: missing")
    x = np.fromfile(path, np.float32)
    if x.size % n:
        sys.exit(f"{path}: {x.size} floats, not whole planes of {n}")
    if x.size < (count or 1) * n:
        sys.exit(f"{path}: {x.size // n} planes of {n}, fewer than {count or 1}")
    x = x.reshape(-1, n)[:count].astype(np.float64)
    if not np.isfinite(x).all():
        sys.exit(f"{path}: non-finite values")
    return x
