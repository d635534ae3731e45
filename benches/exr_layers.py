"""Reading mcdenoise's EXR files (statistics, outputs, references) into
numpy: every channel as a flat f64 array, and a layer's channels stacked.
Used by `auto_oidn.py`, `auto_fallback.py`, `fresh_sample_error.py` and,
through `auto_oidn.load`, `quality_table.py`.
"""
import sys

import numpy as np
import OpenEXR


class Layers(dict):
    """A file's channels by name, and the file's `path` for messages."""

    def __init__(self, path, channels):
        super().__init__(channels)
        self.path = path


def layers(path):
    """Every channel of the EXR at `path` (`"color.R"`, `"albedo.G"`, …)
    as a flat f64 array in row order. Exits with the path in the message
    when the file cannot be read."""
    try:
        with OpenEXR.File(path, separate_channels=True) as f:
            return Layers(path, {k: np.asarray(v.pixels, dtype=np.float64).ravel()
                                 for k, v in f.channels().items()})
    except Exception as e:  # OpenEXR raises plain exceptions for missing or bad files
        sys.exit(f"{path}: {e}")


def stack(d, layer, comps):
    """The channels `comps` of `layer` from `layers`' result, shape
    (len(comps), pixels). Exits naming the file and the missing channel."""
    missing = [f"{layer}.{c}" for c in comps if f"{layer}.{c}" not in d]
    if missing:
        sys.exit(f"{d.path}: no channel {', '.join(missing)} (has {', '.join(sorted(d))})")
    return np.stack([d[f"{layer}.{c}"] for c in comps])
