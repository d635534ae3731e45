"""AUTO-FALLBACK's probe: `auto`'s blend without the members that kept
their input at a pixel.

LP and APR keep a pixel's input where their pixel test left out every
prediction (LP-PIXEL-TEST, APR-PIXEL-TEST); their local dimension `d_i`
is then 0. This recomputes `auto`'s blend (auto_members.py's rule) from
the members run alone (each with its own outlier stage and, for LP,
without GBF-NLM: not exactly as inside `auto`), with and without leaving
such members out, and
prints each rule's rMSE over the blend's as built per case (each
reference's own error subtracted) and the geometric mean per spp.

    target/release/method_mix --scenes <the fifteen> --methods none --no-mix --seed S --work DIR > /dev/null
    for each DIR/<scene>-<spp>.exr and m in wlr lp apr:
        mcdenoise denoise DIR/<scene>-<spp>.exr -o OUT/<scene>@<spp>-<m>.exr --method m \\
            --input-blend=off --pyramid=off --debug-layers --error
    target/oidn-venv/bin/python benches/auto_fallback.py DIR OUT

Rules: `each` leaves a member out where its `d_i` is 0; `both` leaves
LP and APR out where both have `d_i = 0`; `both-v0` the same except at
pixels whose input variance is 0 in every channel; `both-flat` as `both`,
only where the 3×3 neighbourhood's albedo and normal (the input's, raw)
differ from the centre's by less than 0.1.
"""
import collections
import glob
import math
import os
import sys

import numpy as np

from auto_members import blend
from auto_oidn import Work, corrected, rmse
from exr_layers import layers, stack

MEMBERS = ["wlr", "lp", "apr"]


def spread(planes, w, h):
    """Per pixel, the largest absolute difference of any channel from the
    centre's over the 3×3 neighbourhood (borders clamped)."""
    a = planes.reshape(-1, h, w)
    p = np.pad(a, ((0, 0), (1, 1), (1, 1)), mode="edge")
    m = np.zeros((h, w))
    for dy in range(3):
        for dx in range(3):
            m = np.maximum(m, np.abs(p[:, dy:dy + h, dx:dx + w] - a).max(0))
    return m.ravel()


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    work, out = sys.argv[1], sys.argv[2]
    cases = sorted({os.path.basename(p).rsplit("-", 1)[0] for p in glob.glob(f"{out}/*@*-apr.exr")},
                   key=lambda c: (int(c.split("@")[1]), c))
    if not cases:
        sys.exit(f"{out}: no <scene>@<spp>-apr.exr")
    folder = Work(work, cases[0])
    acc = collections.defaultdict(list)
    for case in cases:
        scene, spp = case.split("@")
        r = folder.ref(case)
        err = folder.ref_error(scene, r)
        stats = layers(f"{work}/{scene}-{spp}.exr")
        d = {m: layers(f"{out}/{case}-{m}.exr") for m in MEMBERS}
        cols = [stack(d[m], "color", "RGB") for m in MEMBERS]
        errs = [stack(d[m], "error", "RGB") for m in MEMBERS]
        fell = {m: d[m]["debug.dim"] == 0 if "debug.dim" in d[m] else d[m]["debug.apr_trace"] == 0
                for m in ("lp", "apr")}
        both = fell["lp"] & fell["apr"]
        v0 = stack(stats, "color_variance", "RGB").max(0) == 0
        flat = np.maximum(spread(stack(stats, "albedo", "RGB"), folder.w, folder.h),
                          spread(stack(stats, "normal", "XYZ"), folder.w, folder.h)) < 0.1
        rules = {
            "each": [None, fell["lp"], fell["apr"]],
            "both": [None, both, both],
            "both-v0": [None, both & ~v0, both & ~v0],
            "both-flat": [None, both & flat, both & flat],
        }

        def score(excluded):
            f = blend(cols, errs, folder.w, folder.h, excluded)
            return corrected(rmse(f.T, r), err)

        base = score(None)
        row = {k: score(v) / base for k, v in rules.items()}
        for k, v in row.items():
            acc[(int(spp), k)].append(v)
        print(f"{case}: blend {base:.5f} " + " ".join(f"{k} {v:.3f}" for k, v in row.items()), flush=True)
    for (spp, k), v in sorted(acc.items()):
        g = math.exp(sum(map(math.log, v)) / len(v))
        print(f"{spp} spp {k}: geometric mean {g:.3f}, worst {max(v):.3f}, best {min(v):.3f} ({len(v)} cases)")


if __name__ == "__main__":
    main()
