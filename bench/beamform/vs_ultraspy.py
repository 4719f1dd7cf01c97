"""`usray beamform` as a whole process against ultraspy's steady-state delay-and-sum
on the same data and grid, side by side in one run.

Data: PyMUST's point targets (shared/data/peers/points: 3 plane waves -10/0/+10 deg,
128 elements, 1596 samples at 30.4 MHz). Grid: x = -12.5..12.5 mm, z = 5..35 mm at
0.1 mm (251 x 301): bench/beamform/points_grid.toml, run at F# 0 (full aperture,
PyMUST's default) and at F# 1.75 (ultraspy's default).

usray is timed as a user runs it: the whole process (start, reading the channel
files, IQ demodulation, DAS, envelope, log compression, writing bmode.npy, bmode.png
and the figure's PNG and SVG). ultraspy is timed in steady state inside one Python
process, after numba's JIT compile: `beamform` then `compute_envelope` (the
modulus for IQ; demodulation of the beamformed RF for RF), on IQ data already
demodulated (`is_iq=True`; its `rf2iq` is timed separately) and on RF
(`is_iq=False`, its faster mode). The runs alternate, REPEATS rounds, medians reported; the ratio is
against the faster ultraspy mode.

Run from the workspace root, after `cargo build --release -p usray-cli`:
    python3 -m venv /tmp/peersvenv && /tmp/peersvenv/bin/pip install pymust ultraspy
    /tmp/peersvenv/bin/python bench/beamform/vs_ultraspy.py ../shared/data/peers
Environment: REPEATS (default 7), THREADS (default "1,2").
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
REPEATS = int(os.environ.get("REPEATS", "7"))
THREADS = [int(t) for t in os.environ.get("THREADS", "1,2").split(",")]
channels = os.path.join(root, "points.json")
scene_text = open("bench/beamform/points_grid.toml").read()

rf = np.load(os.path.join(root, "points.npy")).astype(np.float32)  # [3, 128, 1596]
meta = json.load(open(channels))
angles = [t["angle_rad"] for t in meta["transmits"]]
fs, fc = meta["sampling_frequency_hz"], meta["center_frequency_hz"]
x = np.linspace(-12.5e-3, 12.5e-3, 251)
z = np.linspace(5e-3, 35e-3, 301)
xe = (np.arange(128) - 63.5) * 0.3e-3
nt = len(angles)
geom = np.repeat(np.stack([xe, np.zeros(128), np.zeros(128)])[:, None, :], nt, axis=1).astype(np.float32)
delays = np.stack([xe * np.sin(a) / 1540.0 - (xe * np.sin(a) / 1540.0).min() for a in angles])
scan = GridScan(x, z, on_gpu=False)
iq = usig.rf2iq(rf, fc, fs, 0.0, order=5, bandwidth=77.0)


def ultraspy_das(is_iq, f_number):
    bf = DelayAndSum(is_iq=is_iq, on_gpu=False)
    for k, v in [
        ("emitted_probe", geom), ("received_probe", geom),
        ("emitted_thetas", np.zeros((nt, 128))), ("received_thetas", np.zeros((nt, 128))),
        ("delays", delays), ("transmissions_idx", list(range(nt))), ("sound_speed", 1540.0),
        ("f_number", max(f_number, 1e-6)), ("t0", 0.0), ("sampling_freq", fs),
        ("central_freq", fc), ("bandwidth", 77.0),
    ]:
        bf.update_setup(k, v)
    data = iq if is_iq else rf
    run = lambda: bf.compute_envelope(bf.beamform(data, scan), scan)  # DAS + envelope
    run()  # numba JIT compile, not timed
    return run


def timed(f):
    t = time.perf_counter()
    f()
    return time.perf_counter() - t


print(f"{REPEATS} alternating rounds; load average {os.getloadavg()[0]:.2f} at start", flush=True)
with tempfile.TemporaryDirectory() as out:
    for f_number in [0.0, 1.75]:
        scene = os.path.join(out, f"grid_f{f_number}.toml")
        open(scene, "w").write(scene_text.replace("f_number = 0.0", f"f_number = {f_number}"))
        cmd = lambda th: subprocess.run(
            [usray, "beamform", channels, "--scene", scene, "--out", out, "--threads", str(th)],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
        das_iq, das_rf = ultraspy_das(True, f_number), ultraspy_das(False, f_number)
        for threads in THREADS:
            numba.set_num_threads(threads)
            cmd(threads)  # warm the page cache
            u, di, dr, r = [], [], [], []
            for _ in range(REPEATS):
                u.append(timed(lambda: cmd(threads)))
                di.append(timed(das_iq))
                dr.append(timed(das_rf))
                r.append(timed(lambda: usig.rf2iq(rf, fc, fs, 0.0, order=5, bandwidth=77.0)))
            mu, mi, mr, m2 = (np.median(v) for v in (u, di, dr, r))
            print(
                f"F# {f_number}, {threads} thread(s): usray beamform process {mu*1e3:.0f} ms | "
                f"ultraspy DAS+envelope IQ {mi*1e3:.0f} ms (rf2iq +{m2*1e3:.0f}), RF {mr*1e3:.0f} ms | "
                f"ultraspy/usray {min(mi, mr)/mu:.2f}x",
                flush=True,
            )
print(f"load average {os.getloadavg()[0]:.2f} at end")
