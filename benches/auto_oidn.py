"""`auto`'s rMSE over OIDN's on method_mix's uniform built-in cases.

Reads method_mix's JSON lines (with an `auto` column) and its work folder,
where `benches/oidn.sh` has written `oidn-<scene>-<spp>.exr` beside each
`<scene>-<spp>.exr`. Each reference's own error is estimated from the two
cached renders whose mean it is (mcdenoise's reference cache) and subtracted from
both rMSEs (never below a tenth of the raw value). Prints one line per case
and the geometric mean per spp; with OUT, writes the rows as JSON lines.

    target/oidn-venv/bin/python benches/auto_oidn.py WORK LINES.jsonl [OUT.jsonl]
"""
import collections
import glob
import itertools
import json
import math
import os
import sys

import numpy as np

from exr_layers import layers, stack
from mix_dump import planes


def load(path):
    """The colour of the EXR at `path`, shape (pixels, 3)."""
    return stack(layers(path), "color", "RGB").T


def rmse(x, r):
    return float(((x - r) ** 2 / (r ** 2 + 0.01)).mean())


def corrected(raw, err):
    return max(raw - err, 0.1 * raw)


class Work:
    """method_mix's work folder: its dumped references (planar f32 RGB) and
    each reference's own error, from the two cached renders whose mean it is."""

    def __init__(self, work, first_case):
        scene, spp = first_case.split("@")
        found = glob.glob(f"{work}/{scene}@{spp}-*-ref.bin")
        if not found:
            sys.exit(f"{work}: no {scene}@{spp}-<w>x<h>-ref.bin (method_mix's work folder?)")
        self.work = work
        self.size = found[0].rsplit("-", 2)[1]
        self.w, self.h = map(int, self.size.split("x"))
        # The cache as `mcdenoise` finds it (src/render/reference.rs, cache_dir).
        if os.environ.get("MCDENOISE_CACHE"):
            cache = os.environ["MCDENOISE_CACHE"]
        elif os.environ.get("XDG_CACHE_HOME"):
            cache = os.path.join(os.environ["XDG_CACHE_HOME"], "mcdenoise")
        else:
            cache = os.path.expanduser("~/.cache/mcdenoise")
        renders = collections.defaultdict(list)
        for p in sorted(glob.glob(f"{cache}/ref-*-{self.size}-k*-s*.exr")):
            renders[os.path.basename(p).rsplit("-s", 1)[0]].append(p)
        # Every pair of renders of one scene, K and size (more than two where a
        # table used --reference-renders 4): the reference is one pair's mean.
        self.means = []
        for ps in renders.values():
            images = [load(p) for p in ps]
            for a, b in itertools.combinations(images, 2):
                self.means.append((a, (a.astype(np.float32) + b.astype(np.float32)) * 0.5))
        self.errors = {}

    def ref(self, case):
        return planes(f"{self.work}/{case}-{self.size}-ref.bin", self.w * self.h, 3).T

    def ref_error(self, scene, r):
        if scene not in self.errors:
            self.errors[scene] = next((rmse(a, r) for a, m in self.means
                                       if np.allclose(m, r, rtol=1e-5, atol=1e-7)), None)
        if self.errors[scene] is None:
            sys.exit(f"{scene}: no cached pair of renders whose mean is the reference")
        return self.errors[scene]


def main():
    work, lines = sys.argv[1], sys.argv[2]
    rows = [json.loads(l) for l in open(lines) if l.strip()]
    folder = Work(work, rows[0]["case"])
    ref, ref_error = folder.ref, folder.ref_error
    out, by_spp = [], collections.defaultdict(list)
    for row in rows:
        scene, spp = row["case"].split("@")
        r = ref(row["case"])
        oidn = rmse(load(f"{work}/oidn-{scene}-{spp}.exr"), r)
        err = ref_error(scene, r)
        ratio = corrected(row["auto"], err) / corrected(oidn, err)
        by_spp[int(spp)].append(ratio)
        print(f"{row['case']}: ref. error {err:.2e}, auto {row['auto']:.5f}, "
              f"OIDN {oidn:.5f}, auto / OIDN {ratio:.3f}")
        out.append({"case": row["case"], "input": row["input"], "auto": row["auto"],
                    "auto.mean": row["auto.mean"], "oidn": oidn, "ref_error": err,
                    "auto/oidn": ratio})
    for spp in sorted(by_spp):
        v = by_spp[spp]
        g = math.exp(sum(map(math.log, v)) / len(v))
        print(f"{spp} spp: geometric mean {g:.3f}, below OIDN on {sum(x < 1 for x in v)} of {len(v)}")
    if len(sys.argv) > 3:
        with open(sys.argv[3], "w") as f:
            for o in out:
                f.write(json.dumps(o) + "\n")


if __name__ == "__main__":
    main()
