"""Turn the raw k-Wave runs of the given cases into usray channel data (CONTRACT §2):
<out>/<case>.npy ([3, 64, 1920] float32) + <case>.json, plus a B-mode PNG per case for a look.
Usage: python finalize.py OUT_DIR CASE [CASE ...]   (raw runs are read from $KWAVE_SCRATCH/raw)"""
import sys, json, os, numpy as np
HERE = os.path.dirname(os.path.abspath(__file__)); sys.path.insert(0, HERE)
from common import *
from post import *

def sidecar():
    # The scanner's belief: 1480 m/s, whatever the case's true water speed.
    return {
        "format": "usray-channels/1",
        "sampling_frequency_hz": FS_OUT,
        "t0_s": T0_OUT,
        "sound_speed_m_s": C_TX,
        "center_frequency_hz": F0,
        "probe": {"kind": "linear", "n_elements": NEL, "pitch_m": PITCH, "element_width_m": WIDTH},
        "transmits": [{"kind": "plane_wave", "angle_rad": float(np.deg2rad(a))} for a in ANGLES],
        "pulse": {"kind": "gaussian_tone_burst", "cycles": NCYC, "envelope_sigma_s": SIGMA_T,
                  "carrier": "-sin(2*pi*f*t)*exp(-t^2/(2*sigma^2)), t from the envelope centre",
                  "time_reference": "envelope centre"},
        "amplitude_unit": "Pa per 1 Pa source pressure",
        "simulation": "k-wave-python 0.6.2, 2-D (x, z); scattered field = total minus a run of the same background without the target"
                      + f"; k-space reference speed {C_REF:g} m/s; time step {DT * 1e9:g} ns",
    }

if __name__ == "__main__":
    out, cases = sys.argv[1], sys.argv[2:]
    os.makedirs(out, exist_ok=True)
    for case in cases:
        ch = channels(case)
        tmp = os.path.join(out, case + ".tmp.npy"); np.save(tmp, ch); os.replace(tmp, os.path.join(out, case + ".npy"))
        js = os.path.join(out, case + ".json")
        with open(js + ".tmp", "w") as f:
            json.dump(sidecar(), f, indent=2)
        os.replace(js + ".tmp", js)
        g = GEOMS[CASES[case]["geom"]]
        bmode_png(ch, CASES[case]["c_w"], os.path.join(out, case + "_bmode.png"),
                  f"{case}: compounded, 60 dB, c = {CASES[case]['c_w']:.0f}",
                  r_in=g["r_out"] - CASES[case]["wall"], centre=g["centre"], r_out=g["r_out"])
        print(case, ch.shape, "peak", float(np.abs(ch).max()), flush=True)
