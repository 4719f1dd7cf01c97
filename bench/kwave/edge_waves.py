"""The transmit aperture's edge waves in k-Wave's free field against the closed form of
usray's `integrator::edge` (docs/architecture.md, "Edge waves").

A background run (no target) records the transmitted field on the axis at 3, 6 and 9 mm
(`cal` in the raw run). After the plane wave, the two edges' waves arrive together, at
(R - z)/c, R = sqrt(x_edge^2 + z^2), with amplitude 2 |E| / sqrt(2 pi k R) relative to it,
E = -cos(theta)/u (rigid kernel: k-Wave's sources are monopoles), u = x_edge/R at 0 deg.
The soft-baffle kernel (Rayleigh-Sommerfeld, an extra cos(psi)) is printed beside it.

    python3 bench/kwave/edge_waves.py $KWAVE_SCRATCH/raw/ref1480_+0.npz
"""
import sys
import numpy as np
import scipy.signal as ss
from common import DT, C_W, F0, XEL, WIDTH

d = np.load(sys.argv[1])
cal, zs = d["cal"].astype(float), d["cal_z"]
k = 2 * np.pi * F0 / C_W
x_edge = XEL[-1] + WIDTH / 2
for z, trace in zip(zs, cal):
    env = np.abs(ss.hilbert(trace))
    i0 = np.argmax(env)
    r = np.hypot(x_edge, z)
    delay = (r - z) / C_W
    j0, w = i0 + int(round(delay / DT)), int(0.4e-6 / DT)
    j = j0 - w + np.argmax(env[j0 - w:j0 + w])
    rigid = 2 / (x_edge / r) / np.sqrt(2 * np.pi * k * r)
    soft = rigid * z / r
    print(f"z {z * 1e3:.0f} mm: edge waves +{(j - i0) * DT * 1e6:.2f} us (closed form {delay * 1e6:.2f}), "
          f"{20 * np.log10(env[j] / env[i0]):.1f} dB (closed form {20 * np.log10(rigid):.1f}; soft baffle {20 * np.log10(soft):.1f})")
