"""Every method's rMSE over OIDN's on method_mix's uniform built-in cases.

Reads method_mix's JSON lines (any methods; several files are merged by
case, so methods run separately on the same renders can be joined) and its
work folder, where `benches/oidn.sh` has written `oidn-<scene>-<spp>.exr`
beside each `<scene>-<spp>.exr`. Each reference's own error (from its two
cached renders) is subtracted from every rMSE, never below a tenth of the
raw value, as in `auto_oidn.py`. Prints Markdown tables: per case each
method's rMSE and (in brackets) its ratio to OIDN's; per case the image
mean over the reference's of OIDN and each method; per method and spp: the geometric mean of the ratios to OIDN, the
ratio of the summed rMSE, the cases below OIDN, the worst ratio and the
worst output over input.

    target/oidn-venv/bin/python benches/quality_table.py WORK LINES.jsonl [LINES.jsonl ...]
"""
import collections
import json
import math
import sys

from auto_oidn import Work, corrected, load, rmse

ORDER = ["none", "wlr", "lp", "apr", "aos", "auto"]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    work = sys.argv[1]
    rows = {}
    for path in sys.argv[2:]:
        for line in open(path):
            if line.strip():
                row = json.loads(line)
                have = rows.setdefault(row["case"], {})
                if "input" in have and have["input"] != row["input"]:
                    sys.exit(f"{path}: {row['case']} has another input than the lines before "
                             "(other renders or seed)")
                have.update(row)
    cases = list(rows)
    methods = [m for m in ORDER if m != "none" and any(m in r for r in rows.values())]
    folder = Work(work, cases[0])
    ratios = collections.defaultdict(list)
    sums = collections.defaultdict(float)
    oidn_sums = collections.defaultdict(float)
    worst = collections.defaultdict(lambda: (0.0, ""))
    over_input = collections.defaultdict(float)
    head = ["scene", "spp", "ref. error", "input", "OIDN"] + methods
    print("| " + " | ".join(head) + " |")
    print("|---|" + "---:|" * (len(head) - 1))
    mean_rows = []
    for case in cases:
        row = rows[case]
        scene, spp = case.split("@")
        r = folder.ref(case)
        o = load(f"{work}/oidn-{scene}-{spp}.exr")
        err = folder.ref_error(scene, r)
        oidn = rmse(o, r)
        cells = [scene, spp, f"{err:.1e}", f"{row['input']:.5f}", f"{oidn:.5f}"]
        for m in ["input"] + methods:
            if m not in row:
                cells.append("")
                continue
            q = corrected(row[m], err) / corrected(oidn, err)
            key = (m, int(spp))
            ratios[key].append(q)
            sums[key] += corrected(row[m], err)
            oidn_sums[key] += corrected(oidn, err)
            if q > worst[key][0]:
                worst[key] = (q, scene)
            over_input[key] = max(over_input[key], row[m] / row["input"])
            if m != "input":
                cells.append(f"{row[m]:.5f} ({q:.2f})")
        print("| " + " | ".join(cells) + " |")
        means = [f"{float(o.sum() / r.sum()):.3f}"]
        means += [f"{row[m + '.mean']:.3f}" if m in row else "" for m in methods]
        mean_rows.append([scene, spp] + means)
    print()
    print("| scene | spp | OIDN | " + " | ".join(methods) + " |")
    print("|---|" + "---:|" * (len(methods) + 2))
    for cells in mean_rows:
        print("| " + " | ".join(cells) + " |")
    print()
    print("| method | spp | cases | geometric mean ÷ OIDN | summed ÷ OIDN's | below OIDN | worst ÷ OIDN | worst output ÷ input |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for m in ["input"] + methods:
        for spp in sorted({s for (_, s) in ratios}):
            v = ratios[(m, spp)]
            if not v:
                continue
            g = math.exp(sum(map(math.log, v)) / len(v))
            w, ws = worst[(m, spp)]
            print(f"| {m} | {spp} | {len(v)} | {g:.3f} | {sums[(m, spp)] / oidn_sums[(m, spp)]:.3f} | "
                  f"{sum(x < 1 for x in v)} | {w:.2f} ({ws}) | {over_input[(m, spp)]:.3f} |")


if __name__ == "__main__":
    main()
