"""Write a UFF file with USTB's Python writer (pyuff_ustb) from known synthetic
arrays, and the channel data usray must import from it, for usray's UFF import
tests.

    python3 uff_write.py OUT.uff EXPECTED.json    # EXPECTED.npy beside the .json

The file: a 24-element linear array, 3 plane waves with different transmit delays,
2 frames (4-D data), RF. The expected channel data follow USTB's clock (uff.wave:
time zero is the moment the wave passes the origin; channel_data.time(n) =
initial_time + k/fs + sequence(n).delay), so transmit n has
t0_s = initial_time + delay_n on CONTRACT §1's clock.
"""

import json
import sys

import numpy as np
import pyuff_ustb as pyuff

FS, C, FC = 25e6, 1480.0, 5.2e6
N, PITCH, WIDTH = 24, 0.2e-3, 0.18e-3
ANGLES = [-0.15, 0.0, 0.1]
DELAYS = [1.3e-6, 0.0, 0.7e-6]
INITIAL_TIME = -2.5e-6
NS, FRAMES = 200, 2


def write(uff_path, json_path):
    t, e, w, f = np.meshgrid(np.arange(NS), np.arange(N), np.arange(3), np.arange(FRAMES), indexing="ij")
    data = (np.sin(0.05 * t + 0.3 * e) * (w + 1) + 0.25 * f).astype(np.float32)  # [time, channel, wave, frame]
    waves = [
        pyuff.Wave(
            wavefront=pyuff.Wavefront.plane,
            source=pyuff.Point(distance=np.inf, azimuth=a, elevation=0.0),
            origin=pyuff.Point(distance=0.0, azimuth=0.0, elevation=0.0),
            delay=d,
            sound_speed=C,
        )
        for a, d in zip(ANGLES, DELAYS)
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

    transmits = [
        {"kind": "plane_wave", "angle_rad": a, "t0_s": INITIAL_TIME + d, "frame": f}
        for f in range(FRAMES)
        for a, d in zip(ANGLES, DELAYS)
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
    # usray's [transmit, element, sample], transmits frame-major.
    samples = data.transpose(3, 2, 1, 0).reshape(FRAMES * 3, N, NS)
    np.save(json_path[: -len(".json")] + ".npy", np.ascontiguousarray(samples))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    write(sys.argv[1], sys.argv[2])
