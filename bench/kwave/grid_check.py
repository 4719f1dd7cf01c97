"""What k-Wave's grid puts in the benchmark's data: the ring g1 without an effect at 0 deg, made
on the benchmark's grid and on a finer one, side by side (docs/diagnosis.md, Known limits,
"k-Wave's grid"), optionally with a usray render's channels.

    KWAVE_SCRATCH=/tmp/kw1 python sim.py ref1480:0 g1_none:0
    KWAVE_SCRATCH=/tmp/kw2 KWAVE_GRID_DIVISOR=2 python sim.py ref1480:0 g1_none:0
    python3 grid_check.py /tmp/kw1/raw /tmp/kw2/raw [RENDER/channels.npy]

Per element (31, 16, 4): the envelope's maximum in 1-us windows, dB against the benchmark
grid's wall echo; then the wall echoes' spectral centroids (elements 16-47)."""
import sys
import numpy as np
from scipy.signal import hilbert

FS, T_LEAD, T_END = 40e6, 2.5e-6, 50e-6      # output rate; sim time of the wave's t = 0; sim length


def scattered(raw_dir):
    """g1_none minus ref1480 at 0 deg, at 40 MHz from t = 0, and its t0 (k-Wave's additive source
    leaves dt/2 early)."""
    runs = [np.load(f"{raw_dir}/{c}_+0.npz")["rf"].astype(float) for c in ("g1_none", "ref1480")]
    d = runs[0] - runs[1]
    dt = T_END / d.shape[1]
    dec, lead = int(round(1 / (FS * dt))), int(round(T_LEAD / dt))
    return d[:, lead::dec][:, :1900], dt / 2


def centroid_mhz(x, t0, z):
    """Mean spectral centroid of the echo of depth z over elements 16-47."""
    t = t0 + np.arange(x.shape[1]) / FS
    m = (t > 2 * z / 1480 - 1.2e-6) & (t < 2 * z / 1480 + 1.5e-6)
    f = np.fft.rfftfreq(8192, 1 / FS)
    out = []
    for e in range(16, 48):
        p = np.abs(np.fft.rfft(x[e] * m, 8192)) ** 2
        out.append((p * f).sum() / p.sum())
    return np.mean(out) / 1e6


def main():
    series = [("grid", *scattered(sys.argv[1])), ("finer", *scattered(sys.argv[2]))]
    if len(sys.argv) > 3:
        series.append(("usray", np.load(sys.argv[3])[1].astype(float), 0.0))   # its 0 deg transmit
    for el in (31, 16, 4):
        envs = []
        for _, x, t0 in series:
            t = (t0 + np.arange(x.shape[1]) / FS) * 1e6
            envs.append((t, 20 * np.log10(np.abs(hilbert(x[el])) + 1e-12)))
        ref = envs[0][1].max()
        print(f"element {el}: " + ", ".join(f"{n} peak {e[1].max() - ref:+.1f} dB" for (n, _, _), e in zip(series, envs)))
        for tb in np.arange(14.0, 34.0, 1.0):
            row = [e[1][(e[0] >= tb) & (e[0] < tb + 1)].max() - ref for e in envs]
            print(f"  {tb:4.0f}-{tb + 1:.0f} us " + "  ".join(f"{n} {v:6.1f}" for (n, _, _), v in zip(series, row)))
    for n, x, t0 in series:
        print(f"{n}: wall echoes centred at {centroid_mhz(x, t0, 0.011):.3f} (near), {centroid_mhz(x, t0, 0.021):.3f} MHz (far)")


if __name__ == "__main__":
    main()
