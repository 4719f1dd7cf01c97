"""Check a UFF file that usray wrote against the channel data it came from, with
USTB's own Python reader (pyuff_ustb), for usray's UFF export tests.

    python3 uff_check.py FILE.uff CHANNELS.json    # CHANNELS.npy beside the .json

Checks sampling frequency, sound speed, centre frequency, the probe (N, pitch,
element width, geometry: a linear array centred on x = 0), each wave (plane,
azimuth = angle, time origin: initial_time + delay = the transmit's t0_s) and the
data (shape [time, channel, wave(, frame)], values equal in float32).
"""

import json
import sys

import numpy as np
import pyuff_ustb as pyuff


def check(uff_path, json_path):
    meta = json.load(open(json_path))
    samples = np.load(json_path[: -len(".json")] + ".npy")  # [transmit, element, sample]
    cd = pyuff.Uff(uff_path).read("channel_data")
    assert isinstance(cd, pyuff.ChannelData), type(cd)
    assert cd.sampling_frequency == meta["sampling_frequency_hz"], cd.sampling_frequency
    assert cd.sound_speed == meta["sound_speed_m_s"], cd.sound_speed
    assert cd.modulation_frequency == 0
    assert cd.pulse.center_frequency == meta["center_frequency_hz"]

    probe, p = cd.probe, meta["probe"]
    assert isinstance(probe, pyuff.LinearArray), type(probe)
    n = p["n_elements"]
    assert probe.N == n and probe.N_elements == n
    assert probe.pitch == p["pitch_m"] and probe.element_width == p["element_width_m"]
    x = (np.arange(n) - (n - 1) / 2) * p["pitch_m"]
    assert np.allclose(probe.x, x, rtol=0, atol=1e-12), probe.x
    assert not probe.y.any() and not probe.z.any()
    assert np.all(probe.width == p["element_width_m"])

    transmits = meta["transmits"]
    frames = sorted({t["frame"] for t in transmits}) if "frame" in transmits[0] else None
    n_waves = len(transmits) // (len(frames) if frames else 1)
    waves = cd.sequence if isinstance(cd.sequence, list) else [cd.sequence]
    assert len(waves) == n_waves, (len(waves), n_waves)
    for w, (wave, t) in enumerate(zip(waves, transmits)):
        assert wave.wavefront == pyuff.Wavefront.plane
        assert np.isinf(wave.source.distance) and wave.source.elevation == 0
        assert wave.source.azimuth == t["angle_rad"], (w, wave.source.azimuth)
        t0 = t.get("t0_s", meta["t0_s"])
        assert abs(cd.initial_time + wave.delay - t0) <= 1e-15, (w, cd.initial_time, wave.delay, t0)

    data = np.asarray(cd.data)  # [time, channel, wave(, frame)]
    ns = samples.shape[2]
    expect = samples.reshape(len(frames) if frames else 1, n_waves, n, ns).transpose(3, 2, 1, 0)
    if not frames:
        expect = expect[..., 0]
    assert data.shape == expect.shape, (data.shape, expect.shape)
    assert data.dtype == np.float32, data.dtype
    assert np.array_equal(data, expect.astype(np.float32))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    check(sys.argv[1], sys.argv[2])
