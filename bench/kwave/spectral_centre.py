"""Power-weighted mean frequency of channel data, and the centre frequency a scene would take
from it.

For each file (usray channel data: NAME.json beside NAME.npy) the mean frequency of the power
spectrum summed over every transmit and element, `f̄ = Σ f·P(f) / Σ P(f)` over 0.5–5 MHz (the
spectral centroid of spectral-shift attenuation estimation; Kuc, IEEE Trans. ASSP 32(1), 1984).
With a second file, the model's channels (`usray render` of the scene with `dimensions = 2`
for 2-D data), it prints the ratio data/model and the scene's `center_frequency_hz` times it:
the setting measured in docs/diagnosis.md ("The centre frequency is not calibrated by
default"). An attenuation lowers `f̄` too, so take the ratio from an echo without one.

Usage: python3 spectral_centre.py DATA.json [MODEL.json]"""
import json, sys
import numpy as np


def mean_frequency_hz(path_json, band_hz=(0.5e6, 5e6)):
    meta = json.load(open(path_json))
    x = np.load(path_json[: -len(".json")] + ".npy").astype(float)
    power = (np.abs(np.fft.rfft(x, axis=-1)) ** 2).reshape(-1, x.shape[-1] // 2 + 1).sum(0)
    f = np.fft.rfftfreq(x.shape[-1], 1.0 / meta["sampling_frequency_hz"])
    band = (f > band_hz[0]) & (f < band_hz[1])
    return float((f[band] * power[band]).sum() / power[band].sum()), meta


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3) or not all(a.endswith(".json") for a in sys.argv[1:]):
        sys.exit(__doc__)
    data, meta = mean_frequency_hz(sys.argv[1])
    print(f"{sys.argv[1]}: mean frequency {data / 1e6:.3f} MHz")
    if len(sys.argv) == 3:
        model, model_meta = mean_frequency_hz(sys.argv[2])
        ratio = data / model
        print(f"{sys.argv[2]}: mean frequency {model / 1e6:.3f} MHz; data/model {ratio:.4f}; "
              f"center_frequency_hz = {model_meta['center_frequency_hz'] * ratio:.0f}")
