"""Write configs/data/scan.x3p, the example instrument file of configs/scan_tiles.toml.

A self-affine surface (H = 0.8, 128 x 128, rms height 0.2 um, pixel 0.25 um), generated on a
twice larger periodic grid and cropped, with a tilt of 1e-3 as a levelling error would leave,
written as ISO 25178-72 (X3P) in metres from the format's specification.

    python scripts/make_example_scan.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from roughslip.surfaces.synthetic import sample_rng, self_affine
from roughslip.testing import write_x3p

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    a = 0.25e-6
    h = self_affine((128, 128), hurst=0.8, rms_height=0.2e-6, a=a, rng=sample_rng(25178, 0),
                    oversample=2)
    y, x = np.mgrid[0:128, 0:128] * a
    write_x3p(ROOT / "configs" / "data" / "scan.x3p", h + 1e-3 * x + 0.5e-3 * y, a, a)


if __name__ == "__main__":
    main()
