"""Write a UFF file with USTB's Python writer (pyuff_ustb) from known synthetic
arrays, and the channel data usray must import from it, for usray's UFF import
tests.

    python3 uff_write.py OUT.uff EXPECTED.json    # EXPECTED.npy beside the .json

The file: a 24-element linear array, 3 plane waves with different transmit delays,
2 frames (4-D data), RF, on USTB's clock (uff_writer.py).
"""

import numpy as np
import pyuff_ustb as pyuff
import uff_writer

FS, C, FC = 25e6, 1480.0, 5.2e6
N, PITCH, WIDTH = 24, 0.2e-3, 0.18e-3
ANGLES = [-0.15, 0.0, 0.1]
DELAYS = [1.3e-6, 0.0, 0.7e-6]
INITIAL_TIME = -2.5e-6
NS, FRAMES = 200, 2


def write(uff_path, json_path):
    t, e, w, f = np.meshgrid(np.arange(NS), np.arange(N), np.arange(3), np.arange(FRAMES), indexing="ij")
    data = (np.sin(0.05 * t + 0.3 * e) * (w + 1) + 0.25 * f).astype(np.float32)  # [time, channel, wave, frame]
    waves = [
        uff_writer.wave(pyuff.Wavefront.plane, pyuff.Point(distance=np.inf, azimuth=a, elevation=0.0), d, C)
        for a, d in zip(ANGLES, DELAYS)
    ]
    transmits = [
        {"kind": "plane_wave", "angle_rad": a, "t0_s": INITIAL_TIME + d, "frame": f}
        for f in range(FRAMES)
        for a, d in zip(ANGLES, DELAYS)
    ]
    # usray's [transmit, element, sample], transmits frame-major.
    samples = data.transpose(3, 2, 1, 0).reshape(FRAMES * 3, N, NS)
    uff_writer.write(
        uff_path, json_path, fs=FS, c=C, fc=FC, n=N, pitch=PITCH, width=WIDTH, initial_time=INITIAL_TIME,
        waves=waves, data=data, transmits=transmits, samples=samples,
    )


if __name__ == "__main__":
    uff_writer.main(write, __doc__)
