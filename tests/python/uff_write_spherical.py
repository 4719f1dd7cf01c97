"""Write a UFF file of spherical waves with USTB's Python writer (pyuff_ustb),
and the channel data usray must import from it, for usray's UFF import tests.

    python3 uff_write_spherical.py OUT.uff EXPECTED.json    # EXPECTED.npy beside the .json

The file: a 16-element linear array, two spherical waves (`uff.wavefront`
spherical): a virtual source 10 mm behind the array, 2 mm off axis, and a focus
20 mm in front of it, 1 mm off axis, each source given as a `uff.point`
(distance, azimuth). usray reads the first as a `diverging` transmit, the
second as a `focused` one, on USTB's clock (uff_writer.py).
"""

import numpy as np
import pyuff_ustb as pyuff
import uff_writer

FS, C, FC = 20e6, 1540.0, 4e6
N, PITCH, WIDTH = 16, 0.3e-3, 0.27e-3
SOURCES = [(2e-3, -10e-3), (-1e-3, 20e-3)]  # (x, z), m
DELAYS = [0.4e-6, -1.1e-6]
INITIAL_TIME = 1e-6
NS = 120


def write(uff_path, json_path):
    t, e, w = np.meshgrid(np.arange(NS), np.arange(N), np.arange(2), indexing="ij")
    data = (np.cos(0.07 * t - 0.2 * e) * (w + 1)).astype(np.float32)  # [time, channel, wave]
    waves = [
        uff_writer.wave(
            pyuff.Wavefront.spherical,
            pyuff.Point(distance=float(np.hypot(x, z)), azimuth=float(np.arctan2(x, z)), elevation=0.0),
            d,
            C,
        )
        for (x, z), d in zip(SOURCES, DELAYS)
    ]
    # The source positions as usray computes them from (distance, azimuth).
    pts = [(np.hypot(x, z) * np.sin(np.arctan2(x, z)), np.hypot(x, z) * np.cos(np.arctan2(x, z))) for x, z in SOURCES]
    transmits = [
        {"kind": "diverging", "virtual_source_m": [pts[0][0], pts[0][1]], "t0_s": INITIAL_TIME + DELAYS[0]},
        {"kind": "focused", "focus_m": [pts[1][0], pts[1][1]], "t0_s": INITIAL_TIME + DELAYS[1]},
    ]
    samples = data.transpose(2, 1, 0)  # usray's [transmit, element, sample]
    uff_writer.write(
        uff_path, json_path, fs=FS, c=C, fc=FC, n=N, pitch=PITCH, width=WIDTH, initial_time=INITIAL_TIME,
        waves=waves, data=data, transmits=transmits, samples=samples,
    )


if __name__ == "__main__":
    uff_writer.main(write, __doc__)
