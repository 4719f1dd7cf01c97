"""Time PyMUST and ultraspy (CPU) delay-and-sum on the PyMUST point data, as in
shared/data/peers/README.md: 3 plane waves (-10, 0, +10 deg), 128 elements, grid
x = linspace(-12.5, 12.5 mm, 251), z = linspace(5, 35 mm, 301), F# 0, IQ.

Not part of the test suite. Run (from the workspace root):
    python -m venv /tmp/peersvenv && /tmp/peersvenv/bin/pip install pymust ultraspy
    /tmp/peersvenv/bin/python crates/usray-signal/benches/peers_das.py ../shared/data/peers
Throughput = pixel*element*transmit samples per second (the unit of benches/das.rs).
"""
import json
import os
import sys
import time

import numpy as np

root = sys.argv[1] if len(sys.argv) > 1 else "../shared/data/peers"
RF_all = np.load(os.path.join(root, "points.npy"))  # [3, 128, 1596] float32
meta = json.load(open(os.path.join(root, "points.json")))
angles = [t["angle_rad"] for t in meta["transmits"]]
x = np.linspace(-12.5e-3, 12.5e-3, 251)
z = np.linspace(5e-3, 35e-3, 301)
work = x.size * z.size * 128 * len(angles)
REPEATS = int(os.environ.get("REPEATS", "3"))


def median_time(f, repeats=REPEATS):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def report(name, secs):
    print(f"{name}: {secs*1e3:.1f} ms  ({work/secs:.3e} samples/s)", flush=True)


# ---------------------------------------------------------------- PyMUST
import pymust  # noqa: E402

X, Z = np.meshgrid(x, z)


def pymust_param():
    p = pymust.getparam("L11-5v")
    p.fs = 4 * p.fc
    p.c = 1540.0
    return p


def pm_iq():
    out = []
    for t, a in enumerate(angles):
        p = pymust_param()
        out.append(pymust.rf2iq(RF_all[t].T.astype(np.float64), p))
    return out


def pm_mtx(iqs):
    Ms = []
    for t, a in enumerate(angles):
        p = pymust_param()
        dels = pymust.txdelay(p, a)
        p.TXdelay = dels
        Ms.append(pymust.dasmtx(iqs[t], X, Z, dels, p))
    return Ms


iqs = pm_iq()
Ms = pm_mtx(iqs)
vecs = [iq.flatten(order="F") for iq in iqs]
report("pymust rf2iq (3 transmits)", median_time(pm_iq))
report("pymust dasmtx build (3 transmits)", median_time(lambda: pm_mtx(iqs)))
report("pymust DAS apply, sparse M @ IQ", median_time(lambda: [M @ v for M, v in zip(Ms, vecs)]))
g = sum(M @ v for M, v in zip(Ms, vecs))
report("pymust adjoint apply, M^H @ g", median_time(lambda: [M.conj().T @ g for M in Ms]))
report("pymust rf2iq + dasmtx + apply (README pipeline)",
       median_time(lambda: [M @ v.flatten(order='F') for M, v in zip(pm_mtx(pm_iq()), pm_iq())], repeats=1))

# ---------------------------------------------------------------- ultraspy
try:
    import numba
    from ultraspy.beamformers.das import DelayAndSum
    from ultraspy.scan import GridScan
    import ultraspy.cpu.signal as usig

    fs, fc = meta["sampling_frequency_hz"], meta["center_frequency_hz"]
    xe = (np.arange(128) - 63.5) * 0.3e-3
    nt = len(angles)
    # ultraspy wants per-transmission probes: (3, n_tx, n_el), thetas (n_tx, n_el).
    geom = np.repeat(np.stack([xe, np.zeros(128), np.zeros(128)])[:, None, :], nt, axis=1).astype(np.float32)
    # Transmit delays as pymust.txdelay: first element fires at 0; sample 0 at 0.
    delays = np.stack([xe * np.sin(a) / 1540.0 - (xe * np.sin(a) / 1540.0).min() for a in angles])
    bf = DelayAndSum(is_iq=True, on_gpu=False)
    bf.update_setup("emitted_probe", geom)
    bf.update_setup("received_probe", geom)
    bf.update_setup("emitted_thetas", np.zeros((nt, 128)))
    bf.update_setup("received_thetas", np.zeros((nt, 128)))
    bf.update_setup("delays", delays)
    bf.update_setup("transmissions_idx", list(range(len(angles))))
    bf.update_setup("sound_speed", 1540.0)
    bf.update_setup("f_number", 1e-6)  # ~0: full aperture
    bf.update_setup("t0", 0.0)
    bf.update_setup("sampling_freq", fs)
    bf.update_setup("central_freq", fc)
    bf.update_setup("bandwidth", 77.0)
    scan = GridScan(x, z, on_gpu=False)
    iq = usig.rf2iq(RF_all.astype(np.float32), fc, fs, 0.0, order=5, bandwidth=77.0)
    out = bf.beamform(iq, scan)  # numba JIT compile
    for threads in [1, numba.config.NUMBA_NUM_THREADS]:
        numba.set_num_threads(threads)
        report(f"ultraspy DAS (numba CPU, {threads} threads)", median_time(lambda: bf.beamform(iq, scan)))
    # Same image as pymust? (sanity: NCC of dB images over > -40 dB of pymust's)
    ref = np.abs(g.reshape(X.shape, order="F"))
    u = np.abs(np.asarray(out)).reshape(scan.shape).T
    rd, ud = 20 * np.log10(ref / ref.max()), 20 * np.log10(u / u.max() + 1e-30)
    m = rd > -40
    print(f"ultraspy vs pymust dB NCC (> -40 dB): {np.corrcoef(rd[m], ud[m])[0, 1]:.4f}")
except Exception as e:  # report why, do not hide it
    import traceback; traceback.print_exc()
    print(f"ultraspy failed: {type(e).__name__}: {e}")
