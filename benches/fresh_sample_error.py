"""XVAL-STOP's probe: a reconstruction's rMSE estimated from fresh samples.

For each case of a `method_mix` folder A (a method's dumped output `f`
and error estimate `E`), the statistics of the same scene and spp from a
second folder B, rendered with another seed, stand in for the next pass's
samples `z` with variance `v`: the mean over pixels and channels of
`((z − f)² − v) / (f² + 0.01)`
estimates the true rMSE of `f`, bias included. Prints per case the true
rMSE (the reference's own error subtracted), the method's raw estimate
(the mean of `E / (f² + 0.01)`) and the fresh-sample estimate over the true
one, and the latter's standard error (from its per-pixel terms) over
itself; then how often that standard error is at most 0.3 of it, and the
range of the estimate over the truth there.

    target/release/method_mix --scenes <…> --methods auto --no-mix --seed 3 --work A > /dev/null
    target/release/method_mix --scenes <…> --methods none --no-mix --seed 4 --work B > /dev/null
    target/oidn-venv/bin/python benches/fresh_sample_error.py A B auto
"""
import glob
import os
import sys

import numpy as np

from auto_oidn import Work, corrected, rmse
from exr_layers import layers, stack
from mix_dump import planes


def stats(path):
    d = layers(path)
    return stack(d, "color", "RGB"), stack(d, "color_variance", "RGB")


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    a, b, method = sys.argv[1:]
    cases = sorted({os.path.basename(p).rsplit("-", 2)[0] for p in glob.glob(f"{a}/*@*-{method}.bin")},
                   key=lambda c: (c.split("@")[0], int(c.split("@")[1])))
    if not cases:
        sys.exit(f"{a}: no <case>-<w>x<h>-{method}.bin")
    folder = Work(a, cases[0])
    n = folder.w * folder.h
    rows = []
    print("| case | true rMSE | estimate ÷ true | fresh samples ÷ true | its standard error ÷ itself |")
    print("|---|---:|---:|---:|---:|")
    for case in cases:
        scene, spp = case.split("@")
        r = folder.ref(case)
        o = planes(f"{a}/{case}-{folder.size}-{method}.bin", n, 6)
        f, e = o[:3], o[3:]
        true = corrected(rmse(f.T, r), folder.ref_error(scene, r))
        z, v = stats(f"{b}/{scene}-{spp}.exr")
        est = float((e / (f * f + 0.01)).mean())
        term = (((z - f) ** 2 - v) / (f * f + 0.01)).mean(0)
        xv = float(term.mean())
        se = float(term.std() / np.sqrt(term.size)) / abs(xv)
        rows.append((case, xv / true, se))
        print(f"| {case} | {true:.5f} | {est / true:.2f} | {xv / true:.2f} | {se:.2f} |")
    ok = [x for _, x, s in rows if s <= 0.3]
    if not ok:
        print("\nstandard error above 0.3 of the estimate on every case")
        return
    print(f"\nstandard error at most 0.3 of the estimate: {len(ok)} of {len(rows)} cases; "
          f"there the estimate is {min(ok):.2f}–{max(ok):.2f} of the true rMSE, "
          f"within a factor 2 on {sum(0.5 <= x <= 2 for x in ok)}")


if __name__ == "__main__":
    main()
