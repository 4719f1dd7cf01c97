"""Centre frequency of a thin wall's echo: k-Wave's channel data against plane-layer theory.

Theory: the burst of common.pulse (3 cycles at 2.5 MHz) reflected at normal incidence off a
water | wall | water layer, R(f) = r (1 - e^{2ikd}) / (1 - r^2 e^{2ikd}), r = (Z_t - Z_w)/(Z_t + Z_w),
k = 2 pi f / c_t (the plane-layer reflection coefficient, Brekhovskikh, Waves in Layered
Media); for a graded layer (the wall's area fraction blurred by a Gaussian), the
impedance-translation formula over sublayers of 7.5 um. Measured: the spectral centroid of the near and far wall echoes of ring g1 on
elements 16, 32 and 48 at 0 deg in the given channel files (Hann window, 2 us).
Usage: python3 layer_echo.py [data/g1_none.json ...]  (docs/diagnosis.md, Known limits)"""
import json, sys
import numpy as np

Z_W, C_W, RHO_W = 1.48, 1480.0, 1000.0
C_T, RHO_T = 1600.0, 1100.0
Z_T = C_T * RHO_T / 1e6
F = np.linspace(0.05e6, 8e6, 4000)
SIGMA, F0 = 0.2e-6, 2.5e6
BURST = (np.exp(-(2 * np.pi * (F - F0)) ** 2 * SIGMA ** 2 / 2)
         - np.exp(-(2 * np.pi * (F + F0)) ** 2 * SIGMA ** 2 / 2))


def centroid_mhz(spectrum):
    power = np.abs(spectrum) ** 2
    return (F * power).sum() / power.sum() / 1e6


def sharp_layer(d):
    r = (Z_T - Z_W) / (Z_T + Z_W)
    e = np.exp(2j * (2 * np.pi * F / C_T) * d)
    return r * (1 - e) / (1 - r * r * e)


def graded_layer(d, blur, dz=7.5e-6):
    x = np.arange(-0.3e-3, d + 0.3e-3, dz)
    frac = ((x >= 0) & (x < d)).astype(float)
    if blur > 0:
        kern = np.exp(-0.5 * (np.arange(-40, 41) * dz / blur) ** 2)
        frac = np.convolve(frac, kern / kern.sum(), "same")
    rho = (1 - frac) * RHO_W + frac * RHO_T
    kappa = (1 - frac) / (RHO_W * C_W ** 2) + frac / (RHO_T * C_T ** 2)
    c = np.sqrt(1 / (rho * kappa))
    z_in = np.full(F.shape, Z_W, dtype=complex)
    for z_l, c_l in zip((rho * c / 1e6)[::-1], c[::-1]):
        t = np.tan(2 * np.pi * F / c_l * dz)
        z_in = z_l * (z_in + 1j * z_l * t) / (z_l + 1j * z_in * t)
    return (z_in - Z_W) / (z_in + Z_W)


def measured(path):
    meta = json.load(open(path))
    x = np.load(path[:-5] + ".npy").astype(float)
    fs = meta["sampling_frequency_hz"]
    t = meta["t0_s"] + np.arange(x.shape[-1]) / fs
    out = []
    for el in (16, 32, 48):
        for t0, t1 in ((14.0e-6, 16.0e-6), (27.3e-6, 29.3e-6)):
            m = (t > t0) & (t < t1)
            s = np.fft.rfft(x[1, el, m] * np.hanning(m.sum()), 4096)
            f = np.fft.rfftfreq(4096, 1 / fs)
            p = np.abs(s) ** 2
            out.append((f * p).sum() / p.sum() / 1e6)
    return out


print(f"incident burst: {centroid_mhz(BURST):.3f} MHz")
for d in (0.15e-3, 0.2e-3):
    print(f"sharp layer {d * 1e3:.2f} mm: {centroid_mhz(BURST * sharp_layer(d)):.3f} MHz")
for blur in (0.0, 0.0375e-3, 0.075e-3):
    print(f"0.15 mm layer, edges blurred by {blur * 1e3:.4f} mm: "
          f"{centroid_mhz(BURST * graded_layer(0.15e-3, blur)):.3f} MHz")
for path in sys.argv[1:]:
    c = measured(path)
    print(f"{path}: near/far wall echoes {min(c):.2f}-{max(c):.2f} MHz")
