"""`usray beamform` as a whole process against ultraspy's steady-state delay-and-sum
on the same data and grid, side by side in one run.

Data: PyMUST's point targets (shared/data/peers/points: 3 plane waves -10/0/+10 deg,
128 elements, 1596 samples at 30.4 MHz). Grid: x = -12.5..12.5 mm, z = 5..35 mm at
0.1 mm (251 x 301), full aperture (F# 0), IQ beamforming: bench/beamform/points_grid.toml.

usray is timed as a user runs it: the whole process (start, reading the channel
files, IQ demodulation, DAS, envelope, log compression, writing bmode.npy, bmode.png
and the figure). ultraspy is timed in steady state inside one Python process,
after numba's JIT compile: DAS + envelope on IQ data already demodulated (its
`rf2iq` is timed separately). The two alternate, REPEATS rounds, medians reported.

Run from the workspace root, after `cargo build --release -p usray-cli`:
    python3 -m venv /tmp/peersvenv && /tmp/peersvenv/bin/pip install pymust ultraspy
    /tmp/peersvenv/bin/python bench/beamform/vs_ultraspy.py ../shared/data/peers
Environment: REPEATS (default 9), THREADS (default: both 1 and 2).
"""
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import numba
from ultraspy.beamformers.das import DelayAndSum
from ultraspy.scan import GridScan
import ultraspy.cpu.signal as usig

root = sys.argv[1] if len(sys.argv) > 1 else "../shared/data/peers"
usray = os.environ.get("USRAY", "target/release/usray")
REPEATS = int(os.environ.get("REPEATS", "9"))
THREADS = [int(t) for t in os.environ.get("THREADS", "1,2").split(",")]
channels = os.path.join(root, "points.json")
scene = "bench/beamform/points_grid.toml"

rf = np.load(os.path.join(root, "points.npy"))  # [3, 128, 1596] float32
meta = json.load(open(channels))
angles = [t["angle_rad"] for t in meta["transmits"]]
fs, fc = meta["sampling_frequency_hz"], meta["center_frequency_hz"]
x = np.linspace(-12.5e-3, 12.5e-3, 251)
z = np.linspace(5e-3, 35e-3, 301)
xe = (np.arange(128) - 63.5) * 0.3e-3
nt = len(angles)
geom = np.repeat(np.stack([xe, np.zeros(128), np.zeros(128)])[:, None, :], nt, axis=1).astype(np.float32)
delays = np.stack([xe * np.sin(a) / 1540.0 - (xe * np.sin(a) / 1540.0).min() for a in angles])
bf = DelayAndSum(is_iq=True, on_gpu=False)
for k, v in [
    ("emitted_probe", geom), ("received_probe", geom),
    ("emitted_thetas", np.zeros((nt, 128))), ("received_thetas", np.zeros((nt, 128))),
    ("delays", delays), ("transmissions_idx", list(range(nt))), ("sound_speed", 1540.0),
    ("f_number", 1e-6), ("t0", 0.0), ("sampling_freq", fs), ("central_freq", fc),
    ("bandwidth", 77.0),
]:
    bf.update_setup(k, v)
scan = GridScan(x, z, on_gpu=False)
iq = usig.rf2iq(rf.astype(np.float32), fc, fs, 0.0, order=5, bandwidth=77.0)


def ultraspy_das_envelope():
    return np.abs(np.asarray(bf.beamform(iq, scan)))


def ultraspy_rf2iq():
    return usig.rf2iq(rf.astype(np.float32), fc, fs, 0.0, order=5, bandwidth=77.0)


ultraspy_das_envelope()  # numba JIT compile, not timed


def usray_process(threads, out):
    t = time.perf_counter()
    subprocess.run(
        [usray, "beamform", channels, "--scene", scene, "--out", out, "--threads", str(threads)],
        check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    return time.perf_counter() - t


def timed(f):
    t = time.perf_counter()
    f()
    return time.perf_counter() - t


print(f"{REPEATS} alternating rounds; load average {os.getloadavg()[0]:.2f} at start", flush=True)
with tempfile.TemporaryDirectory() as out:
    for threads in THREADS:
        numba.set_num_threads(threads)
        u, d, r = [], [], []
        usray_process(threads, out)  # warm the page cache
        for _ in range(REPEATS):
            u.append(usray_process(threads, out))
            d.append(timed(ultraspy_das_envelope))
            r.append(timed(ultraspy_rf2iq))
        mu, md, mr = np.median(u), np.median(d), np.median(r)
        print(
            f"{threads} thread(s): usray beamform process {mu*1e3:.0f} ms | ultraspy DAS+envelope "
            f"{md*1e3:.0f} ms (+ rf2iq {mr*1e3:.0f} ms) | ratio ultraspy/usray "
            f"{md/mu:.2f}x ({(md+mr)/mu:.2f}x with rf2iq)",
            flush=True,
        )
print(f"load average {os.getloadavg()[0]:.2f} at end")
