#!/usr/bin/env python3
"""Where an image's energy goes, by class of reference value.

    python benches/energy_classes.py WORK CASE [METHOD...]

WORK is a `method_mix --work` folder, CASE a case such as
`night_lights@16` (its `<case>-<W>x<H>-{ref,in,<method>}.bin` planes).
Prints, per class of the reference's grey value (the mean of R, G, B),
the pixel count and the grey sums of the reference, the input and each
method's output (default: wlr and auto); then each image's sum over the
reference's.
"""
import glob
import sys

import numpy as np

from mix_dump import planes


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    work, case = sys.argv[1], sys.argv[2]
    methods = sys.argv[3:] or ["wlr", "auto"]
    refs = glob.glob(f"{glob.escape(work)}/{glob.escape(case)}-*x*-ref.bin")
    if len(refs) != 1:
        sys.exit(f"{work}: expected one {case}-WxH-ref.bin, found {len(refs)}")
    stem = refs[0][: -len("-ref.bin")]
    w, h = map(int, stem.rsplit("-", 1)[1].split("x"))
    n = w * h
    ref = planes(refs[0], n, 3).mean(0)
    if ref.sum() <= 0:
        sys.exit(f"{refs[0]}: the reference's sum is not positive")
    cols = {"input": planes(f"{stem}-in.bin", n, 3).mean(0)}
    for m in methods:
        cols[f"{m} (output)" if m == "input" else m] = planes(f"{stem}-{m}.bin", n, 3).mean(0)
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
