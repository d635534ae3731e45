"""`auto`'s blend of any set of members, offline, on method_mix's dumps.

Runs the rule of `--method auto` (AUTO-BLEND: scores and pairwise
disagreements smoothed by a Gaussian of sigma 1.5, the n-cornered hat,
weights 1/max(score, hat)) on the members' colours and error estimates
that `method_mix` writes (`<case>-<w>x<h>-<method>.bin`: colour R, G, B,
then error R, G, B), for each `+`-joined set of members, and prints each
set's rMSE over OIDN's (both with the reference's own error subtracted,
never below a tenth of the raw value; OIDN's and that error from an
`auto_oidn.py` output) per case, and their geometric mean per spp. Used to
choose AUTO-AOS before it was built; the three members' set reproduces the
dumped `auto` (run with --no-pyramid) to 1e-6.

    target/release/method_mix --methods wlr,lp,apr,aos,auto --no-mix --no-input-blend \
        --no-pyramid --scenes <the fifteen> --spp 16,4 --seed 4 --work DIR > DIR/mm.jsonl
    python benches/auto_members.py DIR docs/data/auto-oidn-128-seed4.jsonl \
        wlr+lp+apr,wlr+lp+apr+aos
"""
import collections
import glob
import itertools
import json
import math
import sys

import numpy as np

from mix_dump import planes

SIGMA, RADIUS = 1.5, 5


def smooth(m, w, h):
    """The Gaussian of spec §0.5 (every pixel valid), clipped at the border."""
    g = np.exp(-np.arange(-RADIUS, RADIUS + 1) ** 2 / (2 * SIGMA * SIGMA))

    def conv(a, axis):
        pad = [(0, 0), (0, 0)]
        pad[axis] = (RADIUS, RADIUS)
        ap = np.pad(a, pad)
        out = np.zeros_like(a)
        for k in range(2 * RADIUS + 1):
            sl = [slice(None), slice(None)]
            sl[axis] = slice(k, k + a.shape[axis])
            out += g[k] * ap[tuple(sl)]
        return out

    m = m.reshape(h, w)
    num = conv(conv(m, 1), 0)
    den = conv(conv(np.ones_like(m), 1), 0)
    return (num / den).ravel()


def blend(cols, errs, w, h, excluded=None):
    """`auto`'s blend of the members' colours and errors (each (3, w·h));
    `excluded`, per member a boolean mask or None: pixels where that
    member's weight is 0 (AUTO-FALLBACK's probe); at least one member must
    keep its weight at every pixel."""
    n = len(cols)
    score = [smooth(np.sum(np.maximum(e, 0) / (c * c + 0.01), 0), w, h) for c, e in zip(cols, errs)]
    fbar = sum(cols) / n
    dis = {}
    for a, b in itertools.combinations(range(n), 2):
        dis[a, b] = dis[b, a] = smooth(np.sum((cols[a] - cols[b]) ** 2 / (fbar * fbar + 0.01), 0), w, h)
    total = sum(dis[a, b] for a, b in itertools.combinations(range(n), 2))
    ws, num = 0, 0
    for a in range(n):
        # Two members cannot tell whose error their disagreement is: their
        # own scores alone.
        hat = (sum(dis[a, b] for b in range(n) if b != a) - total / (n - 1)) / (n - 2) if n > 2 else score[a]
        wa = 1 / np.maximum(np.maximum(score[a], hat), 1e-12)
        if excluded is not None and excluded[a] is not None:
            wa = np.where(excluded[a], 0.0, wa)
        ws, num = ws + wa, num + wa * cols[a]
    return num / ws


def main():
    work, oidn_lines, sets = sys.argv[1], sys.argv[2], [s.split("+") for s in sys.argv[3].split(",")]
    oidn = {json.loads(l)["case"]: json.loads(l) for l in open(oidn_lines) if l.strip()}
    acc = collections.defaultdict(lambda: collections.defaultdict(list))
    for line in open(f"{work}/mm.jsonl"):
        case = json.loads(line)["case"]
        spp = case.split("@")[1]
        ref = next(iter(glob.glob(f"{work}/{case}-*-ref.bin")))
        w, h = map(int, ref.rsplit("-", 2)[1].split("x"))

        def load(m):
            return planes(f"{work}/{case}-{w}x{h}-{m}.bin", w * h)

        r = load("ref")
        o = oidn[case]
        err = o["ref_error"]

        def corrected(raw):
            return max(raw - err, 0.1 * raw)

        row = {}
        for s in sets:
            d = [load(m) for m in s]
            f = blend([x[:3] for x in d], [x[3:] for x in d], w, h)
            raw = float(((f - r) ** 2 / (r * r + 0.01)).mean())
            row["+".join(s)] = corrected(raw) / corrected(o["oidn"])
            acc[spp]["+".join(s)].append(row["+".join(s)])
        print(case, " ".join(f"{k}={v:.3f}" for k, v in row.items()), flush=True)
    for spp, a in acc.items():
        print(spp, " ".join(f"{k}={math.exp(sum(map(math.log, v)) / len(v)):.3f}" for k, v in a.items()))


if __name__ == "__main__":
    main()
