#!/usr/bin/env python3
"""Denoise render-statistics EXRs with Intel Open Image Denoise (pyoidn), the
baseline a user would otherwise pick: RT filter, hdr=True, quality high, with
the file's albedo (clipped to [0, 1]) and normal as auxiliary images, as in
../shared/data/scenes/BASELINES.md. Writes color.R/G/B EXRs that
`mcdenoise compare` reads.

usage: oidn_denoise.py IN.exr OUT.exr [IN.exr OUT.exr ...]
Run through benches/oidn.sh, which makes the virtual environment.
"""
import sys
import time

import numpy as np
import OpenEXR
import pyoidn


def plane(channels, name):
    if name not in channels:
        raise SystemExit(f"missing channel {name}")
    return np.asarray(channels[name].pixels, dtype=np.float32)


def rgb(channels, layer, names):
    return np.stack([plane(channels, f"{layer}.{c}") for c in names], axis=-1)


def main(args):
    if len(args) == 0 or len(args) % 2:
        raise SystemExit(__doc__)
    for src, dst in zip(args[0::2], args[1::2]):
        with OpenEXR.File(src, separate_channels=True) as f:
            ch = f.channels()
            color = np.ascontiguousarray(rgb(ch, "color", "RGB"))
            albedo = np.ascontiguousarray(np.clip(rgb(ch, "albedo", "RGB"), 0.0, 1.0))
            normal = np.ascontiguousarray(np.clip(rgb(ch, "normal", "XYZ"), -1.0, 1.0))
        t0 = time.perf_counter()
        out = pyoidn.denoise(color, albedo, normal, hdr=True, quality="high")
        secs = time.perf_counter() - t0
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        channels = {f"color.{c}": np.ascontiguousarray(out[..., i]) for i, c in enumerate("RGB")}
        with OpenEXR.File(header, channels) as f:
            f.write(dst)
        print(f"{src} -> {dst} ({secs:.2f} s)")


if __name__ == "__main__":
    main(sys.argv[1:])
