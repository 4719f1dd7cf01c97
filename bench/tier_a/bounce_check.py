"""What gives tier (a)'s tube without an effect (a1_none) its false effect: a1_none's data made
again with one of its differences from the model undone or varied (docs/diagnosis.md, tier (a)).

  b4     the data at the model's 4 bounces (the other differences kept)
  clean  no measurement noise
  s2, s3 other seeds of the data (90201, 90301) and of their noise

and a1_tube_b8.toml, the model scene at the data's 8 bounces. Writes OUT_DIR/<variant>/
{truth.toml, channels.npy, channels.json}, OUT_DIR/a1_tube.toml, OUT_DIR/a1_tube_b8.toml and
two tables for bench/run_tier.sh with DATA_DIR = OUT_DIR: variants.tsv (each variant against
the shipped scene) and b8.tsv (a1_none, copied from cases.py's output, and s2, s3 against the
scene at 8 bounces).

Usage: python bounce_check.py OUT_DIR [USRAY] [TIER_A_DIR]
  (TIER_A_DIR: where cases.py wrote tier (a), default /tmp/tier_a)"""
import os, shutil, subprocess, sys
import numpy as np
from cases import HERE, NOISE_DB, truth_text

def variants():
    base = truth_text("a1_none", 0)        # seed 90001, the noise seeded 90001, as cases.py
    return {
        "b4": (base.replace("max_bounces = 8", "max_bounces = 4"), 90001, True),
        "clean": (base, 90001, False),
        "s2": (base.replace("seed = 90001", "seed = 90201"), 90201, True),
        "s3": (base.replace("seed = 90001", "seed = 90301"), 90301, True),
    }

if __name__ == "__main__":
    out = sys.argv[1]
    usray = sys.argv[2] if len(sys.argv) > 2 else "usray"
    tier_a = sys.argv[3] if len(sys.argv) > 3 else "/tmp/tier_a"
    os.makedirs(out, exist_ok=True)
    shutil.copytree(os.path.join(tier_a, "a1_none"), os.path.join(out, "a1_none"), dirs_exist_ok=True)
    for name, (text, seed, noisy) in variants().items():
        d = os.path.join(out, name)
        os.makedirs(d, exist_ok=True)
        truth = os.path.join(d, "truth.toml")
        open(truth, "w").write(text)
        subprocess.run([usray, "render", truth, "--out", d, "--quiet"], check=True)
        if noisy:
            npy = os.path.join(d, "channels.npy")
            ch = np.load(npy)
            rng = np.random.default_rng(seed)
            sigma = np.abs(ch).max() * 10 ** (NOISE_DB / 20)
            np.save(npy + ".tmp.npy", (ch + rng.normal(0.0, sigma, ch.shape)).astype(ch.dtype))
            os.replace(npy + ".tmp.npy", npy)
        print(name, "done", flush=True)
    scene = os.path.join(HERE, "a1_tube.toml")
    shutil.copy(scene, os.path.join(out, "a1_tube.toml"))
    text = open(scene).read()
    assert "max_bounces = 4" in text
    open(os.path.join(out, "a1_tube_b8.toml"), "w").write(text.replace("max_bounces = 4", "max_bounces = 8", 1))
    header = "case\tscene\tmeasured\texpected\n"
    open(os.path.join(out, "variants.tsv"), "w").write(
        header + "".join(f"{v}\ta1_tube.toml\t{v}/channels.json\tnone\n" for v in variants()))
    open(os.path.join(out, "b8.tsv"), "w").write(
        header + "".join(f"{v}\ta1_tube_b8.toml\t{v}/channels.json\tnone\n" for v in ("a1_none", "s2", "s3")))
