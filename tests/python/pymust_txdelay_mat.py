"""PyMUST (SIMUS) point targets seen by a phased (P4-2v) and a convex (C5-2v)
array with diverging and focused transmits, saved as the MATLAB files a PyMUST
user writes: a `param` struct (fs, fc, c, pitch, width, Nelements, radius,
bandwidth, t0, TXdelay as [n_transmits x n_elements]) and int16 RF
(samples x elements x transmits), zlib-compressed. The Rust test
`crates/usray-signal/tests/import_txdelay.rs` imports each with no options,
checks the virtual sources / focus recovered from TXdelay against the ones in
`truth`, and beamforms the point targets.

Run with pymust 0.1.9 and scipy (the peers venv):

    /tmp/peersvenv/bin/python tests/python/pymust_txdelay_mat.py crates/usray-signal/tests/data/import

Writes p4_diverging.mat (3 transmits, TXdelay in seconds), p4_focused.mat
(1 transmit, TXdelay in wavelengths, Verasonics' unit) and c5_diverging.mat
(2 transmits, seconds). PyMUST's clock: each row of TXdelay starts at 0 on the
first-firing element, and SIMUS's sample 0 is that instant (t0 = 0).
"""

import os
import sys
import time

import numpy as np
import pymust
import scipy.io

C = 1540.0


def simulate(param, dels, xs, zs):
    opt = pymust.utils.Options()
    opt.ParPool = False
    rf, _ = pymust.simus(xs, zs, np.ones(len(xs)), dels, param, opt)
    return rf  # [n_t, n_el]


def write(path, param, delays, unit, sources, points_mm):
    """delays: [n_tx, n_el] s (PyMUST txdelay rows); sources: [n_tx, 2] m."""
    xs = np.array([p[0] for p in points_mm]) * 1e-3
    zs = np.array([p[1] for p in points_mm]) * 1e-3
    rfs = []
    for k, d in enumerate(delays):
        t = time.time()
        rfs.append(simulate(param, d[None, :], xs, zs))
        print(f"{path}: transmit {k} SIMUS {rfs[-1].shape} in {time.time() - t:.0f} s", flush=True)
    # Every sample SIMUS returns (its records end after the last echo).
    ns = max(r.shape[0] for r in rfs)
    rf = np.zeros((ns, param.Nelements, len(delays)))
    for k, r in enumerate(rfs):
        rf[: r.shape[0], :, k] = r
    rf_i16 = np.round(rf / np.abs(rf).max() * 32767).astype(np.int16)
    stored = delays * param.fc if unit == "wavelengths" else delays
    p = {
        "fs": float(param.fs),
        "fc": float(param.fc),
        "c": C,
        "pitch": float(param.pitch),
        "width": float(param.width),
        "Nelements": float(param.Nelements),
        "radius": float(param.radius),
        "bandwidth": float(param.bandwidth),
        "t0": 0.0,
        "TXdelay": stored,
    }
    truth = {
        "sources_m": np.asarray(sources, float),
        "points_m": np.stack([xs, zs], axis=1),
        "txdelay_unit": unit,
    }
    scipy.io.savemat(path, {"RF": rf_i16, "param": p, "truth": truth}, do_compression=True)
    print(f"{path}: RF {rf_i16.shape}, {os.path.getsize(path)} bytes", flush=True)


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)

    p4 = pymust.getparam("P4-2v")
    p4.c = C
    p4.fs = 4 * p4.fc
    L = (p4.Nelements - 1) * p4.pitch
    width = np.deg2rad(60.0)
    pts = [(0, 15), (0, 30), (-8, 25), (9, 35)]
    tilts = np.deg2rad([-15.0, 0.0, 15.0])
    delays, sources = [], []
    for tilt in tilts:
        delays.append(pymust.txdelay(p4, tilt, width).ravel())
        x0, z0 = sys.modules["pymust.txdelay"].angles2origo(L, np.array([[tilt]]), np.array([[width]]))
        sources.append((float(np.ravel(x0)[0]), float(np.ravel(z0)[0])))
    write(os.path.join(out, "p4_diverging.mat"), p4, np.array(delays), "seconds", sources, pts)

    focus = (5e-3, 30e-3)
    d = pymust.txdelay(focus[0], focus[1], p4).ravel()
    write(os.path.join(out, "p4_focused.mat"), p4, d[None, :], "wavelengths", [focus],
          [(5, 30), (2, 20), (8, 40)])

    c5 = pymust.getparam("C5-2v")
    c5.c = C
    c5.fs = 4 * c5.fc
    sources = [(-10e-3, -25e-3), (10e-3, -25e-3)]
    delays = [pymust.txdelay(v[0], v[1], c5).ravel() for v in sources]
    write(os.path.join(out, "c5_diverging.mat"), c5, np.array(delays), "seconds", sources,
          [(0, 20), (-10, 30), (12, 38)])


if __name__ == "__main__":
    main()
