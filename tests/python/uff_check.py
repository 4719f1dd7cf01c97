"""Check a UFF file that usray wrote against the channel data it came from, with
USTB's own Python reader (pyuff_ustb), for usray's UFF export tests.

    python3 uff_check.py FILE.uff CHANNELS.json    # CHANNELS.npy beside the .json

Checks sampling frequency, sound speed, centre frequency, the probe (N, pitch,
element width, geometry: a linear array centred on x = 0, or for a convex probe
USTB's curvilinear array of that radius, apex at the origin), each wave (plane:
azimuth = angle, time origin initial_time + delay = the transmit's t0_s;
diverging or focused: spherical, its source at the usray point moved into USTB's
frame, time origin initial_time + delay = t0_s minus the usray time at which the
wave passes USTB's origin) and the data (shape [time, channel, wave(, frame)],
values equal in float32).

USTB's curvilinear array (uff.curvilinear_array; pyuff_ustb CurvilinearArray):
theta_e = (e - (N-1)/2)*2*asin(pitch/(2R)), element at (R sin theta_e, R cos theta_e - R).
usray's (PyMUST's) puts the end elements on z = 0: the same element is s = R - h
deeper, h = R cos(theta_max).
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
    n = p["n_elements"]
    shift = 0.0
    if p["kind"] == "convex":
        assert isinstance(probe, pyuff.CurvilinearArray), type(probe)
        r = p["radius_m"]
        assert probe.radius == r
        theta = (np.arange(n) - (n - 1) / 2) * 2 * np.arcsin(p["pitch_m"] / (2 * r))
        x, z = r * np.sin(theta), r * np.cos(theta) - r
        assert np.allclose(probe.theta, theta, rtol=0, atol=1e-12), probe.theta
        shift = r - r * np.cos(theta[-1])
    else:
        assert isinstance(probe, pyuff.LinearArray), type(probe)
        x = (np.arange(n) - (n - 1) / 2) * p["pitch_m"]
        z = np.zeros(n)
    assert probe.N == n and probe.N_elements == n
    assert probe.pitch == p["pitch_m"] and probe.element_width == p["element_width_m"]
    assert np.allclose(probe.x, x, rtol=0, atol=1e-12), probe.x
    assert np.allclose(probe.z, z, rtol=0, atol=1e-12), probe.z
    assert not probe.y.any()
    assert np.all(probe.width == p["element_width_m"])
    c = meta["sound_speed_m_s"]

    transmits = meta["transmits"]
    frames = sorted({t["frame"] for t in transmits}) if "frame" in transmits[0] else None
    n_waves = len(transmits) // (len(frames) if frames else 1)
    waves = cd.sequence if isinstance(cd.sequence, list) else [cd.sequence]
    assert len(waves) == n_waves, (len(waves), n_waves)
    for w, (wave, t) in enumerate(zip(waves, transmits)):
        assert wave.source.elevation == 0
        t0 = t.get("t0_s", meta["t0_s"])
        if t["kind"] == "plane_wave":
            assert wave.wavefront == pyuff.Wavefront.plane
            assert np.isinf(wave.source.distance)
            assert wave.source.azimuth == t["angle_rad"], (w, wave.source.azimuth)
            th = t["angle_rad"]
            passes_ustb_origin = shift * np.cos(th) / c
        else:
            assert wave.wavefront == pyuff.Wavefront.spherical
            vx, vz = t["virtual_source_m"] if t["kind"] == "diverging" else t["focus_m"]
            sx = wave.source.distance * np.sin(wave.source.azimuth)
            sz = wave.source.distance * np.cos(wave.source.azimuth)
            assert abs(sx - vx) <= 1e-15 and abs(sz - (vz - shift)) <= 1e-15, (w, sx, sz, vx, vz)
            d = np.hypot(vx, shift - vz)
            if t["kind"] == "diverging":
                passes_ustb_origin = (d - np.hypot(vx, vz)) / c
            else:
                passes_ustb_origin = (np.hypot(vx, vz) - d) / c  # USTB's origin lies before the focus
        ustb_t0 = t0 - passes_ustb_origin
        assert abs(cd.initial_time + wave.delay - ustb_t0) <= 1e-15, (w, cd.initial_time, wave.delay, ustb_t0)

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
