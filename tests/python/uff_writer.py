"""What the UFF writer scripts (uff_write.py, uff_write_spherical.py) share:
a linear array's channel data written with USTB's Python writer (pyuff_ustb),
and beside it the channel data usray must import from that file.

Both follow USTB's clock (uff.wave: time zero is the moment the wave passes the
origin; channel_data.time(n) = initial_time + k/fs + sequence(n).delay), so
transmit n has t0_s = initial_time + delay_n on CONTRACT §1's clock.
"""

import json
import sys

import numpy as np
import pyuff_ustb as pyuff

ORIGIN = pyuff.Point(distance=0.0, azimuth=0.0, elevation=0.0)


def wave(wavefront, source, delay, sound_speed):
    """One transmit: a wave of `wavefront` from the point `source`, through the origin."""
    return pyuff.Wave(wavefront=wavefront, source=source, origin=ORIGIN, delay=delay, sound_speed=sound_speed)


def write(uff_path, json_path, *, fs, c, fc, n, pitch, width, initial_time, waves, data, transmits, samples):
    """Write `data` ([time, channel, wave(, frame)], float32) of an `n`-element
    linear array with the sequence `waves` to `uff_path`, and the expected
    usray channel data to `json_path` (metadata with `transmits`) and the .npy
    beside it (`samples`, usray's [transmit, element, sample])."""
    cd = pyuff.ChannelData(
        sampling_frequency=fs,
        initial_time=initial_time,
        sound_speed=c,
        modulation_frequency=0.0,
        sequence=waves,
        probe=pyuff.LinearArray(N=n, pitch=pitch, element_width=width, element_height=5e-3, origin=ORIGIN),
        pulse=pyuff.Pulse(center_frequency=fc, fractional_bandwidth=0.6, phase=0.0, waveform=np.zeros(1)),
        data=data,
    )
    cd.write(uff_path, "channel_data", ignore_missing_compulsory_fields=True)  # no apodization

    meta = {
        "format": "usray-channels/1",
        "sampling_frequency_hz": fs,
        "t0_s": initial_time,
        "sound_speed_m_s": c,
        "center_frequency_hz": fc,
        "probe": {"kind": "linear", "n_elements": n, "pitch_m": pitch, "element_width_m": width},
        "transmits": transmits,
    }
    json.dump(meta, open(json_path, "w"), indent=1)
    np.save(json_path[: -len(".json")] + ".npy", np.ascontiguousarray(samples))


def main(write_files, doc):
    """Run `write_files(OUT.uff, EXPECTED.json)` from the command line."""
    if len(sys.argv) != 3:
        sys.exit(doc)
    write_files(sys.argv[1], sys.argv[2])
