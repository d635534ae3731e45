"""Put some layers of one statistics EXR into another (feature swaps).

    target/oidn-venv/bin/python benches/swap_layers.py SRC.exr FEAT.exr OUT.exr LAYER[,LAYER...]

Writes OUT.exr: SRC.exr with every channel of the named layers (e.g.
`position,position_variance,position_covariance`) taken from FEAT.exr, a
render of the same scene and size (more samples, or another seed). Then
`mcdenoise denoise OUT.exr --method M` shows what those layers cost the
method (FEATURE-SHARED-NOISE).
"""
import sys

import numpy as np
import OpenEXR


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    src, feat, out, names = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4].split(",")
    with OpenEXR.File(src, separate_channels=True) as f:
        header, channels = dict(f.header()), dict(f.channels())
    with OpenEXR.File(feat, separate_channels=True) as g:
        other = g.channels()
        for name in names:
            keys = [k for k in other if k.split(".")[0] == name]
            if not keys:
                sys.exit(f"{feat}: no layer {name}")
            for k in keys:
                if k not in channels:
                    sys.exit(f"{src}: no channel {k}")
                if other[k].pixels.shape != channels[k].pixels.shape:
                    sys.exit(f"{feat}: {k} has another size than in {src}")
                channels[k] = OpenEXR.Channel(np.array(other[k].pixels))
    OpenEXR.File(header, channels).write(out)


if __name__ == "__main__":
    main()
