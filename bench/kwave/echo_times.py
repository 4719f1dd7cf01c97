"""Echo times of ring g1's walls in channel data, against ray geometry.

For each file (usray channel data: NAME.json beside NAME.npy) and the 0° transmit, the
envelope peak of the near wall's and the far wall's echo on elements 0, 8, 16, 24 and 31,
minus the geometric time of the wall's first face (a plane wave at 1480 m/s reflected at
the specular point of the outer face of the near wall, of the inner face of the far wall;
the far wall's time ignores the 0.15 mm wall crossed on the way). The thin wall's two faces
put the peak about half their 0.19 µs spacing late; what matters is the difference between
files. Usage: python3 echo_times.py A.json [B.json ...]  (docs/diagnosis.md, Known limits)"""
import json, sys
import numpy as np
from scipy.optimize import brentq
from scipy.signal import hilbert

C, ZC, R, WALL, PITCH = 1480.0, 16e-3, 5e-3, 0.15e-3, 0.3e-3


def load(path):
    meta = json.load(open(path))
    x = np.load(path[:-5] + ".npy").astype(float)
    return x, meta["t0_s"] + np.arange(x.shape[-1]) / meta["sampling_frequency_hz"]


def near_time(xe):
    f = lambda phi: R * np.sin(phi) + (ZC - R * np.cos(phi)) * np.tan(2 * phi) - xe
    phi = brentq(f, -0.7, 0.7)
    z = ZC - R * np.cos(phi)
    return z * (1 + 1 / np.cos(2 * phi)) / C


def far_time(xe):
    ri = R - WALL
    f = lambda phi: ri * np.sin(phi) - (ZC + ri * np.cos(phi)) * np.tan(2 * phi) - xe
    phi = brentq(f, -0.6, 0.6)
    z = ZC + ri * np.cos(phi)
    return z * (1 + 1 / np.cos(2 * phi)) / C


def peak(x, t, t_geo):
    """Envelope peak within ±1 µs of t_geo, refined by a parabola (s)."""
    e = np.abs(hilbert(x))
    i = np.argmax(np.where(np.abs(t - t_geo) < 1e-6, e, 0))
    a, b, c = e[i - 1 : i + 2]
    return t[i] + 0.5 * (a - c) / (a - 2 * b + c) * (t[1] - t[0])


if __name__ == "__main__":
    data = [(p, *load(p)) for p in sys.argv[1:]]
    print("element  " + "  ".join(f"{p.split('/')[-1]:>24s}" for p, _, _ in data))
    for wall, geo in (("near", near_time), ("far", far_time)):
        for el in (0, 8, 16, 24, 31):
            t_geo = geo((el - 31.5) * PITCH)
            late = [(peak(x[1, el], t, t_geo) - t_geo) * 1e9 for _, x, t in data]
            print(f"{wall:4s} {el:2d}  " + "  ".join(f"{v:+21.1f} ns" for v in late))
