#!/usr/bin/env python3
"""Where an image's energy goes, by class of reference value.

    python benches/energy_classes.py WORK CASE [METHOD...]

WORK is a `method_mix --work` folder, CASE a case such as
`night_lights@16` (its `<case>-<W>x<H>-{ref,in,<method>}.bin` planes).
Prints, per class of the reference's grey value (the mean of R, G, B),
the pixel count and the grey sums of the reference, the input and each
method's output (default: wlr and auto).
"""
import glob
import sys

import numpy as np


def planes(path, n):
    """The first three planes (R, G, B) of a method_mix .bin dump."""
    return np.fromfile(path, np.float32).reshape(-1, n)[:3].astype(np.float64)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    work, case = sys.argv[1], sys.argv[2]
    methods = sys.argv[3:] or ["wlr", "auto"]
    refs = glob.glob(f"{work}/{case}-*x*-ref.bin")
    if len(refs) != 1:
        sys.exit(f"{work}: expected one {case}-WxH-ref.bin, found {len(refs)}")
    stem = refs[0][: -len("-ref.bin")]
    w, h = map(int, stem.rsplit("-", 1)[1].split("x"))
    n = w * h
    ref = planes(refs[0], n).mean(0)
    cols = {"input": planes(f"{stem}-in.bin", n).mean(0)}
    for m in methods:
        cols[m] = planes(f"{stem}-{m}.bin", n).mean(0)
    print(f"| reference class | pixels | reference | {' | '.join(cols)} |")
    print("|---|---:|---:|" + "---:|" * len(cols))
    bounds = [0.0, 0.1, 1.0, 10.0, 100.0, np.inf]
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        m = (ref >= lo) & (ref < hi)
        sums = " | ".join(f"{c[m].sum():.0f}" for c in cols.values())
        print(f"| {lo:g}–{hi:g} | {m.sum()} | {ref[m].sum():.0f} | {sums} |")
    sums = " | ".join(f"{c.sum() / ref.sum():.3f}" for c in cols.values())
    print(f"| all, over the reference's | {n} | 1 | {sums} |")


if __name__ == "__main__":
    main()
