"""The diagnosis's loss on g1_atten at the data's own values against the calibration's proxies.

Writes five variants of `g1.toml` (traced in 2-D, as the diagnosis traces it against
these data), renders each, beamforms the k-Wave data on the same grid, and prints
for each variant the pixel loss of the paper (eq. weighted_l1_l2_loss, λ₁ = λ₂ = 1,
relative levels, seed 1), the same loss with both images floored at −45 and −35 dB,
the loss 22–24 mm deep (1–3 mm under the far wall) and, on the centre columns, the
mean level there in dB. docs/diagnosis.md (tier (b), "Attenuation") quotes its output.

    python3 bench/kwave/proxy_check.py OUT_DIR [USRAY]
"""
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_USRAY = os.path.join(HERE, "..", "..", "target", "release", "usray")
DATA = os.path.join(HERE, "data", "g1_atten.json")

# name: (wall impedance MRayl, attenuation dB/(cm·MHz) in water and wall, roughness,
#        outer radius m, wall thickness m). The radius and roughness are the
#        diagnosis's calibrated ones; "null" is its null refit's point, "thick" the
#        false wall_thickness refit's (diagnosis.json of `bench/run_tier.sh`).
VARIANTS = {
    "truth": (1.76, 0.5, 0.026, 0.004988, 0.15e-3),
    "truth_no_atten": (1.76, 0.0, 0.026, 0.004988, 0.15e-3),
    "null": (3.3115, 0.0, 0.0419, 0.0049884, 0.15e-3),
    "null_atten": (3.3115, 0.5, 0.0419, 0.0049884, 0.15e-3),
    "thick": (3.3158, 0.0, 0.0324, 0.0050287, 0.20678e-3),
}


def scene(z, alpha, rough, radius, thick):
    s = open(os.path.join(HERE, "g1.toml")).read()
    swaps = [
        ("impedance_mrayl = 1.76", f"impedance_mrayl = {z}"),
        ("roughness = 0.05", f"roughness = {rough}\nattenuation_db_cm_mhz = {alpha}"),
        ("impedance_mrayl = 1.48", f"impedance_mrayl = 1.48\nattenuation_db_cm_mhz = {alpha}"),
        ("radius_m = 0.005", f"radius_m = {radius}"),
        ("thickness_m = 0.15e-3", f"thickness_m = {thick}"),
        ('emission = "plane_wave"', 'emission = "plane_wave"\ndimensions = 2'),
    ]
    for old, new in swaps:
        if old not in s:
            sys.exit(f"proxy_check: g1.toml no longer holds `{old}`")
        s = s.replace(old, new)
    return s


def run(usray, *args):
    subprocess.run([usray, *args, "--quiet"], check=True, stdout=subprocess.DEVNULL)


def loss(a, b, floor=0.0):
    d = np.maximum(a, floor) - np.maximum(b, floor)
    return np.abs(d) + d * d


def main():
    out = sys.argv[1]
    usray = sys.argv[2] if len(sys.argv) > 2 else DEFAULT_USRAY
    os.makedirs(out, exist_ok=True)
    first = None
    for name, values in VARIANTS.items():
        path = os.path.join(out, name + ".toml")
        with open(path, "w") as f:
            f.write(scene(*values))
        run(usray, "render", path, "--out", os.path.join(out, name))
        first = first or path
    run(usray, "beamform", DATA, "--scene", first, "--out", os.path.join(out, "measured"))

    measured = np.load(os.path.join(out, "measured", "bmode.npy"))
    nz, nx = measured.shape
    z_mm = 8.0 + 0.2 * np.arange(nz)  # g1.toml's imaging grid: z from 8 mm, 0.2 mm pixels
    under = (z_mm >= 22.0) & (z_mm < 24.0)
    centre = slice(nx // 2 - 5, nx // 2 + 6)
    range_db = 60.0  # g1.toml's dynamic_range_db
    print("variant          loss    floor-45dB floor-35dB  22-24mm  level 22-24mm (dB)")
    for name in ["measured", *VARIANTS]:
        img = np.load(os.path.join(out, name, "bmode.npy"))
        level = np.mean(img[under][:, centre]) * range_db - range_db
        if name == "measured":
            print(f"{name:15s} {'':>7s} {'':>10s} {'':>10s} {'':>8s}  {level:6.1f}")
            continue
        full = loss(img, measured)
        print(f"{name:15s} {full.mean():.4f} {loss(img, measured, 1 - 45 / range_db).mean():10.4f} "
              f"{loss(img, measured, 1 - 35 / range_db).mean():10.4f} {full[under].sum() / full.size:8.4f}  {level:6.1f}")


if __name__ == "__main__":
    main()
