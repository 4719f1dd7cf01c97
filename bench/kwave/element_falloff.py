"""How the ring g1's wall echoes fall off across the array at 0 deg: per element, the envelope's
peak in the near-wall (13.5-17.5 us) and far-wall (26-30 us) windows, dB against the centre
element's (31), for k-Wave runs (g1_none minus ref1480, grid_check.py's `scattered`) and usray
renders (their 0 deg transmit). docs/diagnosis.md, "The element's baffle".

    python3 element_falloff.py /tmp/kw1/raw /tmp/kw2/raw RENDER_SOFT/channels.npy RENDER_RIGID/channels.npy

k-Wave directories (with g1_none_+0.npz and ref1480_+0.npz) and .npy channel files, in any order."""
import sys
import numpy as np
from scipy.signal import hilbert
from grid_check import FS, scattered

N = 1900                                          # samples kept, as grid_check.py keeps them


def kwave(raw_dir):
    return scattered(raw_dir)[0]


def usray(path):
    channels = np.load(path)
    x = channels[len(channels) // 2].astype(float)     # the 0 deg transmit of (-8, 0, 8)
    return np.pad(x, ((0, 0), (0, max(0, N - x.shape[1]))))[:, :N]


series = [(p, usray(p) if p.endswith(".npy") else kwave(p)) for p in sys.argv[1:]]
t = np.arange(N) / FS * 1e6
for lo, hi, wall in [(13.5, 17.5, "near"), (26.0, 30.0, "far")]:
    m = (t > lo) & (t < hi)
    print(f"{wall} wall, dB against element 31:")
    rows = []
    for _, x in series:
        peak = 20 * np.log10(np.abs(hilbert(x, axis=1))[:, m].max(axis=1) + 1e-20)
        rows.append(peak - peak[31])
    for e in (0, 4, 8, 12, 16, 20, 24, 28, 31, 35, 39, 43, 47, 51, 55, 59, 63):
        print(f"  element {e:2d}  " + "  ".join(f"{r[e]:+5.1f}" for r in rows))
print("columns: " + ", ".join(p for p, _ in series))
