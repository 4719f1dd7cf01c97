"""The diagnosis's loss over the ring g1's wall impedance and roughness, against k-Wave data.

Renders `g1.toml` (traced in 2-D, as the diagnosis traces it against these data) on a grid of
wall impedances and roughnesses, with the model's physics chosen by the flags, beamforms the
k-Wave channel data on the same imaging grid, and prints the paper's pixel loss (relative
levels, `proxy_check.loss`) for each point: rows the impedance, columns the roughness. Where
the minimum lies says what the calibration would make of the wall; whether it moves when the
bounces, edge waves or receive baffle change says what the calibrated values stand in for
(docs/diagnosis.md, Known limits, "What the calibrated impedance stood in for").

    python3 bench/kwave/loss_surface.py OUT DATA.json [--bounces 6] [--edge-waves]
        [--rigid] [--rays 400] [--attenuation 0.5] [--angles 0]
        [--impedance 1.76,2.0,2.3,2.6] [--roughness 0.05,0.08,0.12] [--usray BIN]
"""
import argparse
import os

import numpy as np

from proxy_check import DEFAULT_USRAY, loss, run, scene

RADIUS_M, THICKNESS_M = 0.005, 0.15e-3   # g1.toml's ring


def floats(text):
    return [float(v) for v in text.split(",")]


def model_scene(args, impedance, roughness):
    """g1.toml at this wall, traced in 2-D with the physics the flags choose."""
    s = scene(impedance, args.attenuation, roughness, RADIUS_M, THICKNESS_M)
    swaps = [
        ("max_bounces = 4", f"max_bounces = {args.bounces}"),
        ("rays_per_element = 20", f"rays_per_element = {args.rays}"),
        ("dimensions = 2", f"dimensions = 2\nedge_waves = {str(args.edge_waves).lower()}"),
        ("elevation_m = 4.0e-3", "elevation_m = 4.0e-3\nreceive_baffle = "
         + ('"rigid"' if args.rigid else '"soft"')),
    ]
    if args.angles is not None:
        swaps.append(("angles_deg = [-8.0, 0.0, 8.0]", f"angles_deg = [{args.angles}]"))
    for old, new in swaps:
        if old not in s:
            raise SystemExit(f"loss_surface: g1.toml no longer holds `{old}`")
        s = s.replace(old, new)
    return s


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out")
    p.add_argument("data", help="k-Wave channel data (CONTRACT §2), e.g. bench/kwave/data/g1_none.json")
    p.add_argument("--bounces", type=int, default=4)
    p.add_argument("--edge-waves", action="store_true")
    p.add_argument("--rigid", action="store_true", help="probe.receive_baffle = \"rigid\"")
    p.add_argument("--rays", type=int, default=400)
    p.add_argument("--attenuation", type=float, default=0.0, help="dB/(cm·MHz), water and wall")
    p.add_argument("--angles", help="the data's transmit angles when not g1.toml's -8, 0, 8 (e.g. 0.0)")
    p.add_argument("--impedance", type=floats, default=floats("1.5,1.76,2.0,2.3,2.6"))
    p.add_argument("--roughness", type=floats, default=floats("0.02,0.05,0.08,0.12"))
    p.add_argument("--usray", default=DEFAULT_USRAY)
    args = p.parse_args()

    os.makedirs(args.out, exist_ok=True)
    # The data on the scene's imaging grid (every point of the sweep shares it).
    grid = os.path.join(args.out, "measured.toml")
    with open(grid, "w") as f:
        f.write(model_scene(args, args.impedance[0], args.roughness[0]))
    run(args.usray, "beamform", args.data, "--scene", grid, "--out", os.path.join(args.out, "measured"))
    measured = np.load(os.path.join(args.out, "measured", "bmode.npy"))
    table = np.zeros((len(args.impedance), len(args.roughness)))
    for i, z in enumerate(args.impedance):
        for j, r in enumerate(args.roughness):
            name = os.path.join(args.out, f"z{z}_r{r}")
            with open(name + ".toml", "w") as f:
                f.write(model_scene(args, z, r))
            run(args.usray, "render", name + ".toml", "--out", name)
            table[i, j] = loss(np.load(os.path.join(name, "bmode.npy")), measured).mean()
    print("impedance \\ roughness " + " ".join(f"{r:>7.3f}" for r in args.roughness))
    for z, row in zip(args.impedance, table):
        marks = ["*" if v == table.min() else " " for v in row]
        print(f"{z:>21.2f} " + " ".join(f"{v:.4f}{m}" for v, m in zip(row, marks)))


if __name__ == "__main__":
    main()
