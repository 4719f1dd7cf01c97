"""Write PyMUST's point-target channel data (shared/data/peers/points) as MATLAB
files of the layouts users bring, each under other names, sample types and axis
orders, with scipy.io.savemat. The Rust test `import_by_content` imports each with
no flags and checks that its B-mode puts the five points where points.json says.

usage: python3 pymust_as_mat.py POINTS_JSON OUT_DIR

PyMUST's clock (peers README): sample 0 is the instant the first element fires,
and the wave crosses the array centre (L/2)|sin θ|/c later; each file below keeps
that clock (t0 = 0, or no t0 at all), as a Verasonics/PyMUST export would.
"""
import json
import sys
from pathlib import Path

import numpy as np
import scipy.io

points_json, out = Path(sys.argv[1]), Path(sys.argv[2])
meta = json.loads(points_json.read_text())
rf = np.load(points_json.with_suffix(".npy")).astype(np.float64)  # [tx, el, sample]
n_tx, n_el, n_s = rf.shape
angles = np.array([t["angle_rad"] for t in meta["transmits"]])
fs, c = meta["sampling_frequency_hz"], meta["sound_speed_m_s"]
fc, pitch = meta["center_frequency_hz"], meta["probe"]["pitch_m"]
peak = np.abs(rf).max()
out.mkdir(parents=True, exist_ok=True)


def quantise(dtype, full_scale):
    return np.round(rf / peak * full_scale)


sea = np.transpose(rf, (2, 1, 0))  # (samples, elements, angles), MATLAB's usual order

# 1. A nylon-phantom-like export: uint8 centred at 128, `RF1` and `param1` with
#    c, fs, TXangle (radians) and pitch only (no fc, no element count, no t0).
u8 = (np.transpose(quantise(np.uint8, 127), (2, 1, 0)) + 128).astype(np.uint8)
scipy.io.savemat(
    out / "uint8_sea.mat",
    {"RF1": u8, "param1": {"c": c, "fs": fs, "TXangle": angles, "pitch": pitch}},
)

# 2. int16 in C order (angles, elements, samples); a struct of long names, angles in
#    degrees said by the name, and a centre frequency.
i16 = quantise(np.int16, 32767).astype(np.int16)
scipy.io.savemat(
    out / "int16_aes.mat",
    {
        "acq": {
            "sampling_frequency": fs,
            "speed_of_sound": c,
            "element_pitch": pitch,
            "angles_deg": np.degrees(angles),
            "center_frequency": fc,
            "n_elements": float(n_el),
        },
        "channel_data": i16,
        "comment": "PyMUST points, exported by hand",
    },
)

# 3. single, top-level variables only, (elements, samples, angles).
scipy.io.savemat(
    out / "single_esa.mat",
    {
        "fs": fs,
        "c0": c,
        "pitch": pitch,
        "theta": angles,
        "data": np.transpose(rf, (1, 2, 0)).astype(np.float32),
    },
)

# 4. Verasonics-like: uint16 with two identical frames, (samples, elements,
#    angles, frames), a `P` struct whose TXdelay (elements × angles) is in
#    wavelengths with the first-firing element at 0, and t0 = 0.
x = (np.arange(n_el) - (n_el - 1) / 2) * pitch
delays_s = x[:, None] * np.sin(angles)[None, :] / c
delays_s -= delays_s.min(axis=0, keepdims=True)
u16 = (np.transpose(quantise(np.uint16, 32767), (2, 1, 0)) + 32768).astype(np.uint16)
scipy.io.savemat(
    out / "uint16_frames.mat",
    {
        "P": {
            "fs": fs,
            "fc": fc,
            "c": c,
            "pitch": pitch,
            "width": meta["probe"]["element_width_m"],
            "Nelements": np.uint8(n_el),
            "TXangle": angles,
            "TXdelay": delays_s * fc,
            "t0": 0.0,
        },
        "RF": np.stack([u16, u16], axis=3),
    },
)
