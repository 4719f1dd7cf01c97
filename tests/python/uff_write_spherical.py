"""Write a UFF file of spherical waves with USTB's Python writer (pyuff_ustb),
and the channel data usray must import from it, for usray's UFF import tests.

    python3 uff_write_spherical.py OUT.uff EXPECTED.json    # EXPECTED.npy beside the .json

The file: a 16-element linear array, two spherical waves (`uff.wavefront`
spherical): a virtual source 10 mm behind the array, 2 mm off axis, and a focus
20 mm in front of it, 1 mm off axis, each source given as a `uff.point`
(distance, azimuth). usray reads the first as a `diverging` transmit, the
second as a `focused` one, on USTB's clock (t = 0 when the wave passes the
origin; transmit n has t0_s = initial_time + delay_n).
"""

import json
import sys

import numpy as np
import pyuff_ustb as pyuff

FS, C, FC = 20e6, 1540.0, 4e6
N, PITCH, WIDTH = 16, 0.3e-3, 0.27e-3
SOURCES = [(2e-3, -10e-3), (-1e-3, 20e-3)]  # (x, z), m
DELAYS = [0.4e-6, -1.1e-6]
INITIAL_TIME = 1e-6
NS = 120


def write(uff_path, json_path):
    t, e, w = np.meshgrid(np.arange(NS), np.arange(N), np.arange(2), indexing="ij")
    data = (np.cos(0.07 * t - 0.2 * e) * (w + 1)).astype(np.float32)  # [time, channel, wave]
    waves = [
        pyuff.Wave(
            wavefront=pyuff.Wavefront.spherical,
            source=pyuff.Point(distance=float(np.hypot(x, z)), azimuth=float(np.arctan2(x, z)), elevation=0.0),
            origin=pyuff.Point(distance=0.0, azimuth=0.0, elevation=0.0),
            delay=d,
            sound_speed=C,
        )
        for (x, z), d in zip(SOURCES, DELAYS)
    ]
    cd = pyuff.ChannelData(
        sampling_frequency=FS,
        initial_time=INITIAL_TIME,
        sound_speed=C,
        modulation_frequency=0.0,
        sequence=waves,
        probe=pyuff.LinearArray(
            N=N, pitch=PITCH, element_width=WIDTH, element_height=5e-3,
            origin=pyuff.Point(distance=0.0, azimuth=0.0, elevation=0.0),
        ),
        pulse=pyuff.Pulse(center_frequency=FC, fractional_bandwidth=0.6, phase=0.0, waveform=np.zeros(1)),
        data=data,
    )
    cd.write(uff_path, "channel_data", ignore_missing_compulsory_fields=True)  # no apodization

    # The source positions as usray computes them from (distance, azimuth).
    pts = [(np.hypot(x, z) * np.sin(np.arctan2(x, z)), np.hypot(x, z) * np.cos(np.arctan2(x, z))) for x, z in SOURCES]
    transmits = [
        {"kind": "diverging", "virtual_source_m": [pts[0][0], pts[0][1]], "t0_s": INITIAL_TIME + DELAYS[0]},
        {"kind": "focused", "focus_m": [pts[1][0], pts[1][1]], "t0_s": INITIAL_TIME + DELAYS[1]},
    ]
    meta = {
        "format": "usray-channels/1",
        "sampling_frequency_hz": FS,
        "t0_s": INITIAL_TIME,
        "sound_speed_m_s": C,
        "center_frequency_hz": FC,
        "probe": {"kind": "linear", "n_elements": N, "pitch_m": PITCH, "element_width_m": WIDTH},
        "transmits": transmits,
    }
    json.dump(meta, open(json_path, "w"), indent=1)
    samples = data.transpose(2, 1, 0)  # usray's [transmit, element, sample]
    np.save(json_path[: -len(".json")] + ".npy", np.ascontiguousarray(samples))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    write(sys.argv[1], sys.argv[2])
