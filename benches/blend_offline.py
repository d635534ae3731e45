"""The input blend's rule, offline, on `blend_probe --dump`'s files.

Applies the rule of `reference::input_blend` (BLEND-TRIM's floor,
BLEND-RESIDUAL's bound) to a method's output, error estimate and statistics
as `blend_probe --dump` writes them (`<case>-<method>.dump.bin`, 13 f32
planes at 128x128), for each configuration `r:k:s:z`, against the work
folder's references (`<case>-128x128-ref.bin`). Prints, per configuration,
the geometric mean / worst raw rMSE over the first configuration's, at 4,
16 and 64 spp, on the tuning and on the held-out scenes, and the cases whose
output is worse than the input; writes the rows to
`OUT/offline-<method>.json`. The dump holds the output after the outlier
stage's restoration, which the blend runs before: figures differ from the
kernel's by a few per cent where fireflies are (BLEND-AOS). Used to choose
BLEND-AOS.

    target/release/method_mix --scenes <the fifteen> --methods none --no-mix --seed 3 --work DIR
    target/release/blend_probe --work DIR --methods aos --dump OUT
    python benches/blend_offline.py OUT DIR aos 1:2:3:1 1:2:4:0.7 1:2:4:0.6
"""
import sys, os, glob, json
import numpy as np

def windows(a, r, fill):
    """Stack of the (2r+1)^2 shifted copies of 2-D array a (fill outside)."""
    h, w = a.shape
    p = np.pad(a, r, constant_values=fill)
    out = []
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out.append(p[r + dy:r + dy + h, r + dx:r + dx + w])
    return np.stack(out)

def trimmed(vw, valid_w):
    # vw: (K, h, w), valid_w its validity; drop ceil(n/10) largest (<=8, never all)
    n = valid_w.sum(0)
    drop = np.minimum(np.minimum(np.ceil(n / 10), np.maximum(n - 1, 0)), 8)
    s = np.sort(np.where(valid_w, vw, -np.inf), axis=0)[::-1]  # descending, invalid last
    K = vw.shape[0]
    idx = np.arange(K)[:, None, None]
    keep = (idx >= drop) & (idx < n)
    tot = np.where(keep, s, 0).sum(0)
    return tot / np.maximum(n - drop, 1)

def blend(f, e, y, v, spp, r, k, s, z):
    valid = spp >= 1
    vv = np.maximum(v, 0)
    vw = windows(vv, r, 0.0)
    valw = windows(valid, r, False)
    V = np.maximum(vv, trimmed(vw, valw))
    E = np.maximum(e, 0)
    if s > 0:
        d = f - y
        valw = windows(valid, s, False)
        n = valw.sum(0)
        d2 = np.where(valw, windows(d * d, s, 0.0), 0).sum(0)
        mv = np.where(valw, windows(vv, s, 0.0), 0).sum(0)
        mv2 = np.where(valw, windows(vv * vv, s, 0.0), 0).sum(0)
        nn = np.maximum(n, 1)
        B = d2 / nn - mv / nn - z * np.sqrt(mv2 / nn) * np.sqrt(2.0 / nn)
    else:
        B = np.zeros_like(f)
    W = np.maximum(k * E, B)
    with np.errstate(all='ignore'):
        wy = W / (V + W)
        o = f + wy * (y - f)
    ok = valid & np.isfinite(o) & (V + W > 0)
    return np.where(ok, np.maximum(o, 0), f)

def rmse(o, r):
    return float(np.mean((o - r) ** 2 / (r * r + 0.01)))

def load(path, w=128, h=128):
    a = np.fromfile(path, dtype=np.float32).astype(np.float64).reshape(13, h, w)
    return a[0:3], a[3:6], a[6:9], a[9:12], a[12]

def ref(work, case, w=128, h=128):
    return np.fromfile(os.path.join(work, f"{case}-{w}x{h}-ref.bin"), dtype=np.float32).astype(np.float64).reshape(3, h, w)

HELD = {"night_lights", "fence", "window_interior", "panel"}

def run(dumps, work, method, configs):
    rows = []
    for p in sorted(glob.glob(os.path.join(dumps, f"*-{method}.dump.bin"))):
        case = os.path.basename(p)[: -len(f"-{method}.dump.bin")]
        f, e, y, v, spp = load(p)
        R = ref(work, case)
        row = {"case": case, "input": rmse(y, R), "off": rmse(f, R)}
        for name, (r, k, s, z) in configs.items():
            o = np.stack([blend(f[c], e[c], y[c], v[c], spp, r, k, s, z) for c in range(3)])
            row[name] = rmse(o, R)
        rows.append(row)
    return rows

def summary(rows, names, base):
    for name in names:
        out = [name]
        for spp in (4, 16, 64):
            sel = [x for x in rows if x["case"].endswith(f"@{spp}")]
            for held in (False, True):
                s2 = [x for x in sel if (x["case"].split("@")[0] in HELD) == held]
                rat = np.array([x[name] / x[base] for x in s2])
                wc = s2[int(rat.argmax())]["case"].split("@")[0][:6]
                out.append(f"{np.exp(np.log(rat).mean()):.3f}/{rat.max():.2f}{wc}")
        worse = [f"{x['case']} {x[name]/x['input']:.3f}" for x in rows if x[name] > x["input"]]
        print(" ".join(out), "| worse:", ", ".join(worse) or "none")

if __name__ == "__main__":
    dumps, work, method = sys.argv[1:4]
    grid = {}
    for spec in sys.argv[4:]:
        r, k, s, z = spec.split(":")
        grid[spec] = (int(r), float(k), int(s), float(z))
    base = sys.argv[4]
    rows = run(dumps, work, method, grid)
    json.dump(rows, open(os.path.join(dumps, f"offline-{method}.json"), "w"))
    summary(rows, ["off"] + list(grid), base)
