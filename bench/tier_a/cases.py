"""Tier (a) of the diagnosis benchmark (bench/README.md): usray-made "measured" data rendered
unlike the model the diagnosis uses.

Each case is a base scene (a1_tube.toml, a2_sphere.toml, a3_layered.toml) with at most one
effect switched on (two in the compound cases). Its "measured" data are rendered with 10x
the model's rays (200 against 20), the independent sampler (the model: stratified), 8 bounces (the model: 4, or 6 where
a solid cylinder is a wall candidate: usray_optim::diagnosis_bounces), seeds from
another family (90001 + case index; the model's fits use 1 and its held-out seeds 2 + k 2^33),
and white measurement noise at -50 dB of the largest channel sample (seeded, numpy).

Usage: python cases.py OUT_DIR [USRAY]   (USRAY: the usray binary, default `usray`)
Writes OUT_DIR/<case>/truth.toml and OUT_DIR/<case>/channels.{npy,json}, and OUT_DIR/cases.tsv
(case, base scene, expected verdict)."""
import os, subprocess, sys
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
RENDER = {"rays_per_element = 20": "rays_per_element = 200",
          "max_bounces = 4": "max_bounces = 8"}
NOISE_DB = -50.0

def acq(extra):
    """Adds lines to [acquisition] (after its seed line)."""
    return ("seed = 1\n", "seed = 1\n" + extra)

# case: (base scene, expected verdict, [(old, new) text edits of the base scene])
CASES = {
    "a1_none":    ("a1_tube", "none", []),
    "a1_wall":    ("a1_tube", "wall_thickness", [("thickness_m = 0.8e-3", "thickness_m = 1.6e-3")]),
    "a1_atten":   ("a1_tube", "attenuation", [("impedance_mrayl = 1.54\n", "impedance_mrayl = 1.54\nattenuation_db_cm_mhz = 0.5\n")]),
    "a1_speed":   ("a1_tube", "sound_speed", [("sound_speed_m_s = 1540.0\nimpedance", "sound_speed_m_s = 1500.0\nimpedance"),
                                              ("dynamic_range_db = 60.0\n", "dynamic_range_db = 60.0\nsound_speed_m_s = 1540.0\n")]),
    "a2_none":    ("a2_sphere", "none", []),
    "a2_scatter": ("a2_sphere", "volume_scattering", [("roughness = 0.3\n", "roughness = 0.3\nscatterer_density_per_mm3 = 5.0\nscatterer_strength = 0.15\n")]),
    "a2_gain":    ("a2_sphere", "depth_gain", [acq("depth_gain_db_per_cm = 4.0\n")]),
    "a2_pulse":   ("a2_sphere", "pulse_length", [("cycles = 3.0", "cycles = 4.5")]),
    "a3_none":    ("a3_layered", "none", []),
    "a3_atten":   ("a3_layered", "attenuation", [("sound_speed_m_s = 1600.0\nroughness = 0.3\n", "sound_speed_m_s = 1600.0\nroughness = 0.3\nattenuation_db_cm_mhz = 1.0\n")]),
    "a3_wall":    ("a3_layered", "wall_thickness", [("radius_m = 0.003\n", "radius_m = 0.003\nthickness_m = 1.0e-3\n")]),
    "a3_speed":   ("a3_layered", "sound_speed", [("sound_speed_m_s = 1540.0\nimpedance", "sound_speed_m_s = 1570.0\nimpedance"),
                                                 ("dynamic_range_db = 60.0\n", "dynamic_range_db = 60.0\nsound_speed_m_s = 1540.0\n")]),
    # Compound cases (bench/tier_a/compound.tsv): two effects at once, each named by one
    # round of the compound diagnosis. Appended, so the cases above keep their seeds.
    "a1_wall_speed":    ("a1_tube", "wall_thickness+sound_speed",
                         [("thickness_m = 0.8e-3", "thickness_m = 1.6e-3"),
                          ("sound_speed_m_s = 1540.0\nimpedance", "sound_speed_m_s = 1500.0\nimpedance"),
                          ("dynamic_range_db = 60.0\n", "dynamic_range_db = 60.0\nsound_speed_m_s = 1540.0\n")]),
    "a2_pulse_scatter": ("a2_sphere", "pulse_length+volume_scattering",
                         [("cycles = 3.0", "cycles = 4.5"),
                          ("roughness = 0.3\n", "roughness = 0.3\nscatterer_density_per_mm3 = 5.0\nscatterer_strength = 0.15\n")]),
}

def truth_text(case, index):
    base, _, edits = CASES[case]
    text = open(os.path.join(HERE, base + ".toml")).read()
    for old, new in edits:
        assert old in text, (case, old)
        text = text.replace(old, new, 1)
    for old, new in RENDER.items():
        assert old in text, (case, old)
        text = text.replace(old, new, 1)
    text = text.replace("seed = 1\n", f"seed = {90001 + index}\nsampler = \"independent\"\n", 1)
    return f"# Tier (a) truth for {case}: {base}.toml with its effect, rendered unlike the model.\n" + text

if __name__ == "__main__":
    out, usray = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else "usray")
    os.makedirs(out, exist_ok=True)
    rows = []
    for i, case in enumerate(CASES):
        d = os.path.join(out, case)
        os.makedirs(d, exist_ok=True)
        truth = os.path.join(d, "truth.toml")
        open(truth, "w").write(truth_text(case, i))
        # The truth scene names no external files, so it may live in OUT.
        subprocess.run([usray, "render", truth, "--out", d, "--quiet"], check=True)
        npy = os.path.join(d, "channels.npy")
        ch = np.load(npy)
        rng = np.random.default_rng(90001 + i)
        sigma = np.abs(ch).max() * 10 ** (NOISE_DB / 20)
        noisy = (ch + rng.normal(0.0, sigma, ch.shape)).astype(ch.dtype)
        np.save(npy + ".tmp.npy", noisy)
        os.replace(npy + ".tmp.npy", npy)
        base, expected, _ = CASES[case]
        rows.append(f"{case}\t{base}\t{expected}")
        print(case, "done", flush=True)
    open(os.path.join(out, "cases.tsv"), "w").write("case\tscene\texpected\n" + "\n".join(rows) + "\n")
